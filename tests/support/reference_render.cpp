// Double-precision reference tracer and renderer (see reference_render.h).
#include "tests/support/reference_render.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "common/base/error.h"
#include "common/image/image.h"
#include "common/render/render_kernels.h"

namespace rtc::test {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kLeafSize = 4;
constexpr int kBins = 16;
// SAH splits below this depth give way to median splits, which bound the depth (and the
// traversal stack) whatever the input.
constexpr std::uint32_t kSahDepth = 96;
constexpr int kMaxStack = 160;
// Ize 2013: widening the far slab distance by 2 gamma_3 (gamma_n = n u / (1 - n u)) makes the
// double slab test conservative.
constexpr double kGamma3 = 3.0 * 0x1p-53 / (1.0 - 3.0 * 0x1p-53);
constexpr double kFarWiden = 1.0 + 2.0 * kGamma3;

double max3(const glm::dvec3& v) { return std::max(v.x, std::max(v.y, v.z)); }

glm::dvec3 normalize_or(const glm::dvec3& a, const glm::dvec3& fallback) {
  const double len2 = glm::dot(a, a);
  if (!(len2 > 0.0) || !std::isfinite(len2)) return fallback;
  return a / std::sqrt(len2);
}

/// Woop et al. 2013 per-ray constants: the dominant axis kz, the other two (swapped to keep
/// the winding when dir[kz] < 0) and the shear that maps the ray onto +z.
struct Shear {
  int kx = 0, ky = 1, kz = 2;
  double sx = 0.0, sy = 0.0, sz = 1.0;
  explicit Shear(const glm::dvec3& d) {
    const glm::dvec3 a = glm::abs(d);
    kz = a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
    kx = (kz + 1) % 3;
    ky = (kx + 1) % 3;
    if (d[kz] < 0.0) std::swap(kx, ky);
    sx = d[kx] / d[kz];
    sy = d[ky] / d[kz];
    sz = 1.0 / d[kz];
  }
};

/// Watertight test in double; on a hit within (t_min, t_max) fills t, beta, gamma.
bool hit_triangle(const glm::dvec3& org, const Shear& s, const glm::dvec3* v, double t_min, double t_max,
                  double& t, double& beta, double& gamma) {
  const glm::dvec3 a = v[0] - org, b = v[1] - org, c = v[2] - org;
  const double ax = a[s.kx] - s.sx * a[s.kz], ay = a[s.ky] - s.sy * a[s.kz];
  const double bx = b[s.kx] - s.sx * b[s.kz], by = b[s.ky] - s.sy * b[s.kz];
  const double cx = c[s.kx] - s.sx * c[s.kz], cy = c[s.ky] - s.sy * c[s.kz];
  const double u = cx * by - cy * bx;
  const double w_v = ax * cy - ay * cx;
  const double w = bx * ay - by * ax;
  if ((u < 0.0 || w_v < 0.0 || w < 0.0) && (u > 0.0 || w_v > 0.0 || w > 0.0)) return false;
  const double det = u + w_v + w;
  if (det == 0.0 || !std::isfinite(det)) return false;
  const double tt = (u * (s.sz * a[s.kz]) + w_v * (s.sz * b[s.kz]) + w * (s.sz * c[s.kz])) / det;
  if (!(tt > t_min && tt < t_max)) return false;
  t = tt;
  beta = w_v / det;
  gamma = w / det;
  return true;
}

}  // namespace

ReferenceTracer::ReferenceTracer(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles) {
  const auto start = std::chrono::steady_clock::now();
  const std::size_t n = triangles.size();
  verts_.resize(3 * n);
  std::vector<glm::dvec3> centroid;
  std::vector<std::pair<glm::dvec3, glm::dvec3>> box;
  centroid.reserve(n);
  box.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t vi = triangles[i][k];
      RTC_CHECK(vi < positions.size(), "reference tracer: triangle vertex index out of range");
      verts_[3 * i + static_cast<std::size_t>(k)] = glm::dvec3(positions[vi]);
    }
    const glm::dvec3* v = &verts_[3 * i];
    const glm::dvec3 cr = glm::cross(v[1] - v[0], v[2] - v[0]);
    const bool finite = std::isfinite(v[0].x + v[0].y + v[0].z + v[1].x + v[1].y + v[1].z + v[2].x + v[2].y + v[2].z);
    if (!finite || (cr.x == 0.0 && cr.y == 0.0 && cr.z == 0.0)) continue;  // never hits
    order_.push_back(static_cast<std::uint32_t>(i));
    const glm::dvec3 lo = glm::min(glm::min(v[0], v[1]), v[2]);
    const glm::dvec3 hi = glm::max(glm::max(v[0], v[1]), v[2]);
    box.emplace_back(lo, hi);
    centroid.push_back((lo + hi) * 0.5);
  }
  // Boxes and centroids follow order_ positions; keep them permuted together.
  std::vector<std::uint32_t> slot(order_.size());
  for (std::uint32_t i = 0; i < slot.size(); ++i) slot[i] = i;

  nodes_.reserve(2 * (order_.size() / kLeafSize + 1));
  nodes_.push_back(Node{});
  struct Task {
    std::uint32_t node, begin, end, depth;
  };
  std::vector<Task> tasks{{0, 0, static_cast<std::uint32_t>(slot.size()), 0}};
  while (!tasks.empty()) {
    const Task task = tasks.back();
    tasks.pop_back();
    glm::dvec3 lo(kInf), hi(-kInf), clo(kInf), chi(-kInf);
    for (std::uint32_t i = task.begin; i < task.end; ++i) {
      lo = glm::min(lo, box[slot[i]].first);
      hi = glm::max(hi, box[slot[i]].second);
      clo = glm::min(clo, centroid[slot[i]]);
      chi = glm::max(chi, centroid[slot[i]]);
    }
    Node& node = nodes_[task.node];
    node.lo = lo;
    node.hi = hi;
    const std::uint32_t count = task.end - task.begin;
    const glm::dvec3 extent = chi - clo;
    const int axis = extent.x >= extent.y ? (extent.x >= extent.z ? 0 : 2) : (extent.y >= extent.z ? 1 : 2);
    if (count <= kLeafSize || !(extent[axis] > 0.0)) {
      node.first = task.begin;
      node.count = count;
      continue;
    }
    // Binned SAH along the widest centroid axis; the median when the best bin split is empty.
    std::array<std::uint32_t, kBins> bin_count{};
    std::array<glm::dvec3, kBins> bin_lo, bin_hi;
    bin_lo.fill(glm::dvec3(kInf));
    bin_hi.fill(glm::dvec3(-kInf));
    const double scale = kBins / extent[axis];
    auto bin_of = [&](std::uint32_t s) {
      return std::min(kBins - 1, static_cast<int>((centroid[s][axis] - clo[axis]) * scale));
    };
    for (std::uint32_t i = task.begin; i < task.end; ++i) {
      const int b = bin_of(slot[i]);
      ++bin_count[b];
      bin_lo[b] = glm::min(bin_lo[b], box[slot[i]].first);
      bin_hi[b] = glm::max(bin_hi[b], box[slot[i]].second);
    }
    auto area = [](const glm::dvec3& l, const glm::dvec3& h) {
      if (!(h.x >= l.x)) return 0.0;
      const glm::dvec3 d = h - l;
      return d.x * d.y + d.y * d.z + d.z * d.x;
    };
    std::array<double, kBins> right_cost{};
    glm::dvec3 rl(kInf), rh(-kInf);
    std::uint32_t rc = 0;
    for (int b = kBins - 1; b > 0; --b) {
      rl = glm::min(rl, bin_lo[b]);
      rh = glm::max(rh, bin_hi[b]);
      rc += bin_count[b];
      right_cost[b] = area(rl, rh) * rc;
    }
    double best = kInf;
    int best_b = -1;
    glm::dvec3 ll(kInf), lh(-kInf);
    std::uint32_t lc = 0;
    for (int b = 0; b + 1 < kBins; ++b) {
      ll = glm::min(ll, bin_lo[b]);
      lh = glm::max(lh, bin_hi[b]);
      lc += bin_count[b];
      if (lc == 0 || lc == count) continue;
      const double cost = area(ll, lh) * lc + right_cost[b + 1];
      if (cost < best) {
        best = cost;
        best_b = b;
      }
    }
    std::uint32_t mid = 0;
    if (task.depth >= kSahDepth) best_b = -1;
    if (best_b >= 0) {
      mid = static_cast<std::uint32_t>(
          std::partition(slot.begin() + task.begin, slot.begin() + task.end,
                         [&](std::uint32_t s) { return bin_of(s) <= best_b; }) -
          slot.begin());
    } else {
      mid = task.begin + count / 2;
      std::nth_element(slot.begin() + task.begin, slot.begin() + mid, slot.begin() + task.end,
                       [&](std::uint32_t x, std::uint32_t y) { return centroid[x][axis] < centroid[y][axis]; });
    }
    const auto left = static_cast<std::uint32_t>(nodes_.size());
    nodes_.push_back(Node{});
    nodes_.push_back(Node{});
    nodes_[task.node].first = left;
    nodes_[task.node].count = 0;
    tasks.push_back({left, task.begin, mid, task.depth + 1});
    tasks.push_back({left + 1, mid, task.end, task.depth + 1});
  }
  // Leaves index order_ through slot: resolve to triangle ids once.
  std::vector<std::uint32_t> ids(slot.size());
  for (std::size_t i = 0; i < slot.size(); ++i) ids[i] = order_[slot[i]];
  order_ = std::move(ids);
  build_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

template <bool kAny>
RefHit ReferenceTracer::trace(const glm::dvec3& org, const glm::dvec3& dir, double t_min, double t_max,
                              std::uint32_t skip) const {
  RefHit best;
  best.t = t_max;
  if (order_.empty()) return best;
  const Shear shear(dir);
  const glm::dvec3 inv(1.0 / dir.x, 1.0 / dir.y, 1.0 / dir.z);
  // Entry distance of the box, or +inf when the ray's segment misses it.
  auto enter = [&](const Node& n, double far_limit) {
    double t0 = t_min, t1 = far_limit;
    for (int a = 0; a < 3; ++a) {
      if (dir[a] == 0.0) {
        if (org[a] < n.lo[a] || org[a] > n.hi[a]) return kInf;
        continue;
      }
      double tn = (n.lo[a] - org[a]) * inv[a];
      double tf = (n.hi[a] - org[a]) * inv[a];
      if (tn > tf) std::swap(tn, tf);
      t0 = std::max(t0, tn);
      t1 = std::min(t1, tf * kFarWiden);
      if (t0 > t1) return kInf;
    }
    return t0;
  };
  if (enter(nodes_[0], t_max) == kInf) return best;
  std::uint32_t stack[kMaxStack];
  int depth = 0;
  std::uint32_t index = 0;
  for (;;) {
    const Node& n = nodes_[index];
    if (n.count > 0) {
      for (std::uint32_t i = n.first; i < n.first + n.count; ++i) {
        const std::uint32_t id = order_[i];
        if (id == skip) continue;
        double t, beta, gamma;
        // Equal t may still win (higher id): test against the next float above best.t.
        const double limit = kAny ? t_max : std::nextafter(best.t, kInf);
        if (!hit_triangle(org, shear, &verts_[3 * static_cast<std::size_t>(id)], t_min, limit, t, beta, gamma)) continue;
        if (kAny) {
          best = RefHit{t, beta, gamma, id};
          return best;
        }
        if (t < best.t || (t == best.t && (best.prim == kNoHit || id > best.prim))) best = RefHit{t, beta, gamma, id};
      }
    } else {
      const double far_limit = kAny ? t_max : best.t;
      const double t_l = enter(nodes_[n.first], far_limit);
      const double t_r = enter(nodes_[n.first + 1], far_limit);
      if (t_l != kInf && t_r != kInf) {
        const bool left_first = t_l <= t_r;
        RTC_CHECK(depth < kMaxStack, "reference tracer: BVH deeper than its stack");
        stack[depth++] = left_first ? n.first + 1 : n.first;
        index = left_first ? n.first : n.first + 1;
        continue;
      }
      if (t_l != kInf) {
        index = n.first;
        continue;
      }
      if (t_r != kInf) {
        index = n.first + 1;
        continue;
      }
    }
    // Pop the next subtree that can still hold a closer (or tying) hit.
    for (;;) {
      if (depth == 0) return best;
      index = stack[--depth];
      if (enter(nodes_[index], kAny ? t_max : best.t) != kInf) break;
    }
  }
}

RefHit ReferenceTracer::intersect(const glm::dvec3& org, const glm::dvec3& dir, double t_min, double t_max,
                                  std::uint32_t skip) const {
  return trace<false>(org, dir, t_min, t_max, skip);
}

bool ReferenceTracer::occluded(const glm::dvec3& org, const glm::dvec3& dir, double t_min, double t_max,
                               std::uint32_t skip) const {
  return trace<true>(org, dir, t_min, t_max, skip).prim != kNoHit;
}

namespace {

struct RefContext {
  const FrameState& fs;
  const ReferenceTracer& tracer;
  const ReferenceOptions& options;
  ReferenceStats counts;
};

/// Radiance along a ray, the renderer's trace_radiance for one lane, in double.
glm::dvec3 radiance(RefContext& c, const glm::dvec3& org, const glm::dvec3& dir, std::uint32_t skip, int depth,
                    const glm::dvec3& weight) {
  (depth == 0 ? c.counts.primary : c.counts.reflection) += 1;
  const FrameState& fs = c.fs;
  const RefHit hit = c.tracer.intersect(org, dir, 0.0, kInf, skip);
  if (hit.prim == kNoHit) return weight * glm::dvec3(fs.background);

  const FrameGeometry& g = *fs.geometry;
  const glm::uvec3 tri = g.triangles[hit.prim];
  const glm::dvec3 a(g.positions[tri.x]), b(g.positions[tri.y]), cc(g.positions[tri.z]);
  const double alpha = (1.0 - hit.beta) - hit.gamma;
  const glm::dvec3 p = a * alpha + b * hit.beta + cc * hit.gamma;
  glm::dvec3 ng = normalize_or(glm::cross(b - a, cc - a), glm::dvec3(0, 0, 1));
  if (glm::dot(ng, dir) > 0.0) ng = -ng;
  glm::dvec3 n = ng;
  if (g.smooth[hit.prim]) {
    const glm::dvec3 na(g.normals[tri.x]), nb(g.normals[tri.y]), nc(g.normals[tri.z]);
    n = normalize_or(na * alpha + nb * hit.beta + nc * hit.gamma, ng);
    if (glm::dot(n, dir) > 0.0) n = -n;
  }
  const glm::dvec3 view = -normalize_or(dir, glm::dvec3(0, 0, 1));
  const double magnitude = max3(glm::max(glm::max(glm::abs(a), glm::abs(b)), glm::abs(cc)));
  const glm::dvec3 point = p + ng * std::max(magnitude * 0x1p-40, std::numeric_limits<double>::min());
  const Material& m = fs.materials[g.material_ids[hit.prim]];
  const glm::dvec3 diffuse(m.diffuse), specular(m.specular);

  glm::dvec3 local = glm::dvec3(fs.ambient) * diffuse + glm::dvec3(m.emission);
  for (const PointLight& light : fs.lights) {
    const glm::dvec3 d = glm::dvec3(light.position) - point;
    if (!(glm::dot(d, ng) > 0.0)) continue;
    const glm::dvec3 to_light = normalize_or(d, n);
    const double n_dot_l = glm::dot(n, to_light);
    if (!(n_dot_l > 0.0)) continue;
    ++c.counts.shadow;
    if (c.tracer.occluded(point, d, 0.0, 1.0, hit.prim)) continue;
    glm::dvec3 contrib = diffuse * n_dot_l;
    if (max3(specular) > 0.0) {
      const glm::dvec3 r = n * (2.0 * n_dot_l) - to_light;
      const double r_dot_v = glm::dot(r, view);
      if (r_dot_v > 0.0) contrib += specular * std::pow(r_dot_v, static_cast<double>(m.shininess));
    }
    local += glm::dvec3(light.color) * contrib;
  }
  glm::dvec3 color = weight * local;
  if (!m.reflective || depth >= c.options.max_depth) return color;
  const glm::dvec3 w = weight * specular;
  if (!(max3(w) >= c.options.min_weight) || !(max3(w) > 0.0)) return color;
  glm::dvec3 r = dir - n * (2.0 * glm::dot(dir, n));
  if (!(glm::dot(r, ng) > 0.0)) r = dir - ng * (2.0 * glm::dot(dir, ng));
  return color + radiance(c, point, r, hit.prim, depth + 1, w);
}

}  // namespace

Image reference_render(const FrameState& fs, const ReferenceTracer& tracer, const ReferenceOptions& options,
                       ReferenceStats* stats) {
  const auto start = std::chrono::steady_clock::now();
  Image out(fs.width, fs.height);
  const int spp = std::max(1, fs.settings.spp);
  std::vector<ReferenceStats> row_counts(static_cast<std::size_t>(fs.height));
  tbb::parallel_for(tbb::blocked_range<int>(0, fs.height), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      RefContext c{fs, tracer, options, {}};
      for (int x = 0; x < fs.width; ++x) {
        glm::dvec3 sum(0.0);
        for (int s = 0; s < spp; ++s) {
          double sx, sy;
          sample_offset(s, sx, sy);
          const RayD r = fs.camera_rays.ray_double(x, y, sx, sy);
          sum += radiance(c, r.origin, r.dir, kNoHit, 0, glm::dvec3(1.0));
        }
        sum /= static_cast<double>(spp);
        float* p = out.pixel(x, y);
        p[0] = static_cast<float>(sum.x);
        p[1] = static_cast<float>(sum.y);
        p[2] = static_cast<float>(sum.z);
        p[3] = 1.0f;
      }
      row_counts[static_cast<std::size_t>(y)] = c.counts;
    }
  });
  if (stats != nullptr) {
    *stats = ReferenceStats{};
    for (const ReferenceStats& r : row_counts) {
      stats->primary += r.primary;
      stats->shadow += r.shadow;
      stats->reflection += r.reflection;
    }
    stats->ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  }
  return out;
}

double display_value(float linear) {
  const double v = std::clamp(static_cast<double>(linear), 0.0, 1.0);
  return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

std::uint64_t count_non_finite(const Image& image) {
  std::uint64_t bad = 0;
  for (float v : image.rgba) bad += std::isfinite(v) ? 0 : 1;
  for (float v : image.normal) bad += std::isfinite(v) ? 0 : 1;
  for (float v : image.depth) bad += (std::isnan(v) || v == -std::numeric_limits<float>::infinity()) ? 1 : 0;
  return bad;
}

ImageError image_error(const Image& image, const Image& reference, std::vector<double>* per_pixel) {
  if (image.width != reference.width || image.height != reference.height) {
    throw Error("image_error: image is " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                ", reference " + std::to_string(reference.width) + "x" + std::to_string(reference.height));
  }
  ImageError e;
  e.non_finite = count_non_finite(image);
  double sum2 = 0.0;
  std::uint64_t over = 0;
  const std::size_t pixels = static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height);
  if (per_pixel != nullptr) per_pixel->assign(pixels, 0.0);
  for (std::size_t i = 0; i < pixels; ++i) {
    double pixel_max = 0.0;
    for (int ch = 0; ch < 3; ++ch) {
      const float v = image.rgba[4 * i + static_cast<std::size_t>(ch)];
      // A NaN counts as the largest possible error.
      const double d = std::isnan(v) ? 1.0
                                     : std::abs(display_value(v) - display_value(reference.rgba[4 * i + static_cast<std::size_t>(ch)]));
      sum2 += d * d;
      pixel_max = std::max(pixel_max, d);
    }
    e.max_abs = std::max(e.max_abs, pixel_max);
    over += pixel_max > 1.0 / 255.0 ? 1 : 0;
    if (per_pixel != nullptr) (*per_pixel)[i] = pixel_max;
  }
  const double n = 3.0 * static_cast<double>(std::max<std::size_t>(pixels, 1));
  e.rmse = std::sqrt(sum2 / n);
  e.psnr_db = e.rmse > 0.0 ? 20.0 * std::log10(1.0 / e.rmse) : std::numeric_limits<double>::infinity();
  e.pct_over_1_255 = 100.0 * static_cast<double>(over) / static_cast<double>(std::max<std::size_t>(pixels, 1));
  return e;
}

}  // namespace rtc::test
