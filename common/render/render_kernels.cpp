// Per-ISA tile rendering: packets of 2x2 primary rays, packet shadow rays per light, mirror
// reflections recursing as packets, Whitted/Phong shading (Wald et al. 2001, section 3).
//
// Shading runs lane by lane in scalar float code (common/render/shading.h and the few lines
// below), the same code at every packet width, so a pixel is the same bits whether its rays
// travelled in a packet or alone.
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include "common/accel/kd_traverse.h"
#include "common/accel/trace.h"
#include "common/image/image.h"
#include "common/math/det_math.h"
#include "common/render/frame_state.h"
#include "common/render/render_kernels.h"
#include "common/render/shading.h"
#include "common/render/temporal.h"

RTC_ISA_BEGIN
namespace rtc::RTC_ISA_NS {
namespace {

inline float max3(const glm::vec3& a) { return std::max(a.x, std::max(a.y, a.z)); }

/// Per-lane results of tracing a packet one bounce deeper.
template <int N>
struct Lanes {
  glm::vec3 weight[N];  // throughput carried by each lane
  glm::vec3 color[N];   // radiance accumulated, already weighted
};

/// Closest hits of the lanes in `lanes_mask`, from rtc's kd-trees or the external tracer.
template <int N>
void closest_hits(const FrameState& fs, const RayLanes<N>& rays, unsigned lanes_mask, RayHit (&out)[N]) {
  if (fs.tracer != nullptr) {
    RayQuery q[N];
    RayHit h[N];
    int n = 0;
    for (int i = 0; i < N; ++i) {
      if ((lanes_mask >> i) & 1u) q[n++] = rays.query(i);
    }
    fs.tracer->intersect(fs.tracer->context, q, h, static_cast<std::size_t>(n));
    n = 0;
    for (int i = 0; i < N; ++i) {
      if ((lanes_mask >> i) & 1u) out[i] = h[n++];
    }
    return;
  }
  const RayPacket<N> p = rays.packet();
  HitPacket<N> hit{p.t_max, vfloat<N>(0.0f), vfloat<N>(0.0f), vint<N>(-1)};
  // The static meshes' tree first (most hits are there), then each moving mesh's: every tree
  // starts from the hits found so far, which end its lanes' segments, and replaces one only
  // with a nearer triangle or one at the same t with a higher id, so the result is the bits of
  // one tree over all triangles (kd_traverse.h, intersect).
  const vbool<N> active = vbool<N>::from_bits(lanes_mask);
  for (const std::shared_ptr<const KdTree>& tree : fs.geometry->trees) intersect<N>(*tree, p, active, hit);
  float t[N], beta[N], gamma[N];
  std::int32_t prim[N];
  hit.t.store(t);
  hit.beta.store(beta);
  hit.gamma.store(gamma);
  hit.prim.store(prim);
  for (int i = 0; i < N; ++i) out[i] = RayHit{t[i], beta[i], gamma[i], static_cast<std::uint32_t>(prim[i])};
}

/// Occlusion of the lanes in `lanes_mask`, as a lane bit mask. `by_static` (optional) gets the
/// lanes blocked by meshes that never move (FrameGeometry::first_tree_static).
template <int N>
unsigned occluded_lanes(const FrameState& fs, const RayLanes<N>& rays, unsigned lanes_mask,
                        unsigned* by_static = nullptr) {
  if (by_static != nullptr) *by_static = 0;
  if (fs.tracer != nullptr) {
    RayQuery q[N];
    std::uint8_t occ[N];
    int n = 0;
    for (int i = 0; i < N; ++i) {
      if ((lanes_mask >> i) & 1u) q[n++] = rays.query(i);
    }
    fs.tracer->occluded(fs.tracer->context, q, occ, static_cast<std::size_t>(n));
    unsigned out = 0;
    n = 0;
    for (int i = 0; i < N; ++i) {
      if (((lanes_mask >> i) & 1u) && occ[n++] != 0) out |= 1u << i;
    }
    return out;
  }
  // Any tree's hit occludes: a lane leaves the query once one tree has blocked it.
  const RayPacket<N> p = rays.packet();
  unsigned blocked = 0;
  for (const std::shared_ptr<const KdTree>& tree : fs.geometry->trees) {
    const unsigned open = lanes_mask & ~blocked;
    if (open == 0) break;
    blocked |= bits(occluded<N>(*tree, p, vbool<N>::from_bits(open)));
    if (by_static != nullptr && fs.geometry->first_tree_static && tree == fs.geometry->trees.front()) {
      *by_static = blocked;
    }
  }
  return blocked;
}

/// First-hit data the image keeps besides colour (sample 0 only).
struct Aov {
  float depth = std::numeric_limits<float>::infinity();
  glm::vec3 normal{0.0f};
};

template <int N>
void trace_radiance(const FrameState& fs, const RayLanes<N>& rays, unsigned active, int depth, Lanes<N>& lanes,
                    Aov* aov, TileRayCounts& counts, MarkRecorder* marks) {
  (depth == 0 ? counts.primary : counts.reflection) += static_cast<std::uint64_t>(std::popcount(active));
  RayHit hit[N];
  closest_hits<N>(fs, rays, active, hit);
  if (marks != nullptr) {
    // Temporal coherence: the voxels the rays crossed up to their hits (all the way on a miss).
    glm::vec3 org[N], dir[N];
    float t_end[N];
    int n = 0;
    for (int i = 0; i < N; ++i) {
      if (!((active >> i) & 1u)) continue;
      const RayQuery q = rays.query(i);
      org[n] = q.org;
      dir[n] = q.dir;
      t_end[n++] = hit[i].prim == kNoHit ? q.t_max : hit[i].t;
    }
    marks->path(n, org, dir, t_end);
  }

  SurfaceSample surf[N];
  glm::vec3 local[N];
  unsigned hit_lanes = 0;
  for (int i = 0; i < N; ++i) {
    if (!((active >> i) & 1u)) continue;
    if (hit[i].prim == kNoHit) {
      lanes.color[i] = lanes.color[i] + lanes.weight[i] * fs.background;
      continue;
    }
    hit_lanes |= 1u << i;
    const RayQuery q = rays.query(i);
    surf[i] = surface_at(fs, q.dir, hit[i].prim, hit[i].beta, hit[i].gamma);
    const Material& m = *surf[i].material;
    local[i] = fs.ambient * m.diffuse + m.emission;
    if (aov != nullptr) {
      // The depth channel gets the distance recomputed in double (exact for grazing rays too).
      const FrameGeometry& g = *fs.geometry;
      const glm::uvec3 tri = g.triangles[hit[i].prim];
      aov[i].depth = refined_distance(q.org, q.dir, g.positions[tri.x], g.positions[tri.y], g.positions[tri.z],
                                      hit[i].t);
      aov[i].normal = surf[i].normal;
    }
  }
  if (hit_lanes == 0) return;
  if (marks != nullptr && !fs.lights.empty()) marks->shaded();

  // One packet of shadow rays per light (Wald et al. 2001, section 3).
  for (const PointLight& light : fs.lights) {
    RayLanes<N> shadow;
    glm::vec3 to_light[N];
    unsigned want = 0;
    for (int i = 0; i < N; ++i) {
      if (!((hit_lanes >> i) & 1u)) continue;
      const std::optional<ShadowRay> s = shadow_ray(surf[i], light);
      if (!s) continue;
      want |= 1u << i;
      shadow.set(i, s->ray);
      to_light[i] = s->to_light;
    }
    if (want == 0) continue;
    counts.shadow += static_cast<std::uint64_t>(std::popcount(want));
    unsigned by_static = 0;
    const unsigned blocked = occluded_lanes<N>(fs, shadow, want, marks != nullptr ? &by_static : nullptr);
    if (marks != nullptr) {
      // Temporal coherence: a shadow ray blocked by a mesh that never moves stays blocked
      // whatever moves, so it needs no marks (in an interior most of them; on the office
      // benchmark it halves the tiles retraced). The others may change along their whole way.
      glm::vec3 org[N], dir[N];
      float t_end[N];
      int n = 0;
      for (int i = 0; i < N; ++i) {
        if (!((want >> i) & 1u) || ((by_static >> i) & 1u)) continue;
        const RayQuery q = shadow.query(i);
        org[n] = q.org;
        dir[n] = q.dir;
        t_end[n++] = q.t_max;
      }
      if (n > 0) marks->shadow(n, org, dir, t_end);
    }
    for (int i = 0; i < N; ++i) {
      if (!((want >> i) & 1u) || ((blocked >> i) & 1u)) continue;
      const SurfaceSample& s = surf[i];
      const Material& m = *s.material;
      const float n_dot_l = glm::dot(s.normal, to_light[i]);
      glm::vec3 contrib = m.diffuse * n_dot_l;
      if (max3(m.specular) > 0.0f) {
        const glm::vec3 r = s.normal * (2.0f * n_dot_l) - to_light[i];
        const float r_dot_v = glm::dot(r, s.view);
        if (r_dot_v > 0.0f) contrib = contrib + m.specular * det_powf(r_dot_v, m.shininess);
      }
      local[i] = local[i] + light.color * contrib;
    }
  }

  // Mirror reflections, as one packet per bounce, cut off by depth and by ray weight.
  RayLanes<N> refl;
  Lanes<N> next;
  unsigned bounce = 0;
  for (int i = 0; i < N; ++i) {
    if (!((hit_lanes >> i) & 1u)) continue;
    lanes.color[i] = lanes.color[i] + lanes.weight[i] * local[i];
    const SurfaceSample& s = surf[i];
    const Material& m = *s.material;
    if (!m.reflective || depth >= fs.settings.max_depth) continue;
    const glm::vec3 w = lanes.weight[i] * m.specular;
    if (!(max3(w) >= fs.settings.min_weight) || !(max3(w) > 0.0f)) continue;
    const glm::vec3 d = s.dir;
    glm::vec3 r = d - s.normal * (2.0f * glm::dot(d, s.normal));
    // An interpolated normal can send the mirror ray below the surface; use the true one then.
    if (!(glm::dot(r, s.geometric) > 0.0f)) r = d - s.geometric * (2.0f * glm::dot(d, s.geometric));
    bounce |= 1u << i;
    next.weight[i] = w;
    next.color[i] = glm::vec3(0.0f);
    refl.set(i, RayQuery{s.point, 0.0f, r, std::numeric_limits<float>::infinity()});
  }
  if (bounce == 0) return;
  trace_radiance<N>(fs, refl, bounce, depth + 1, next, nullptr, counts, marks);
  for (int i = 0; i < N; ++i) {
    if ((bounce >> i) & 1u) lanes.color[i] = lanes.color[i] + next.color[i];
  }
}

// Packets of 2x2 pixels (N = 4), 4x2 (N = 8), 4x4 (N = 16); single pixels when N = 1.
template <int N>
void render_tile_impl(const FrameState& fs, int x0, int y0, int w, int h, Image& out, TileRayCounts& counts,
                      MarkRecorder* marks) {
  constexpr int kBlockW = packet_block_width(N);
  constexpr int kBlockH = N / kBlockW;
  const int spp = std::max(1, fs.settings.spp);
  const bool aovs = !out.depth.empty();
  for (int by = 0; by < h; by += kBlockH) {
    for (int bx = 0; bx < w; bx += kBlockW) {
      int px[N], py[N];
      unsigned valid = 0;
      for (int i = 0; i < N; ++i) {
        px[i] = bx + i % kBlockW;
        py[i] = by + i / kBlockW;
        if (px[i] < w && py[i] < h) valid |= 1u << i;
      }
      glm::vec3 sum[N];
      for (glm::vec3& v : sum) v = glm::vec3(0.0f);
      Aov aov[N];
      for (int s = 0; s < spp; ++s) {
        double sx, sy;
        sample_offset(s, sx, sy);
        RayLanes<N> primary;
        for (int i = 0; i < N; ++i) {
          if (!((valid >> i) & 1u)) continue;
          const Ray r = fs.camera_rays.ray(x0 + px[i], y0 + py[i], sx, sy);
          primary.set(i, RayQuery{r.origin, 0.0f, r.dir, std::numeric_limits<float>::infinity()});
        }
        Lanes<N> lanes;
        for (int i = 0; i < N; ++i) {
          lanes.weight[i] = glm::vec3(1.0f);
          lanes.color[i] = glm::vec3(0.0f);
        }
        trace_radiance<N>(fs, primary, valid, 0, lanes, s == 0 ? aov : nullptr, counts, marks);
        for (int i = 0; i < N; ++i) sum[i] = sum[i] + lanes.color[i];
      }
      const float inv_spp = 1.0f / static_cast<float>(spp);
      for (int i = 0; i < N; ++i) {
        if (!((valid >> i) & 1u)) continue;
        float* p = out.pixel(px[i], py[i]);
        const glm::vec3 c = spp == 1 ? sum[i] : sum[i] * inv_spp;
        p[0] = c.x;
        p[1] = c.y;
        p[2] = c.z;
        p[3] = 1.0f;
        if (aovs) {
          const std::size_t idx = static_cast<std::size_t>(py[i]) * static_cast<std::size_t>(w) +
                                  static_cast<std::size_t>(px[i]);
          out.depth[idx] = aov[i].depth;
          out.normal[3 * idx + 0] = aov[i].normal.x;
          out.normal[3 * idx + 1] = aov[i].normal.y;
          out.normal[3 * idx + 2] = aov[i].normal.z;
        }
      }
    }
  }
}

void render_tile_entry(const FrameState& fs, int x0, int y0, int w, int h, bool packets, Image& out,
                       TileRayCounts& counts, MarkRecorder* marks) {
  if (marks != nullptr && marks->grid_empty() && fs.lights.empty()) marks = nullptr;  // nothing to record
  if (packets) {
    render_tile_impl<RTC_ISA_WIDTH>(fs, x0, y0, w, h, out, counts, marks);
  } else {
    render_tile_impl<1>(fs, x0, y0, w, h, out, counts, marks);
  }
}

}  // namespace

const RenderKernels& render_kernels_for_isa() {
  static const RenderKernels kernels{Isa::RTC_ISA_ENUM, &render_tile_entry};
  return kernels;
}

}  // namespace rtc::RTC_ISA_NS
RTC_ISA_END
