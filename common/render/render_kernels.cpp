// Per-ISA tile rendering: packets of 2x2 primary rays, packet shadow rays per light, mirror
// reflections recursing as packets, Whitted/Phong shading (Wald et al. 2001, section 3).
//
// Shading runs lane by lane in scalar float code, the same code at every packet width, so a
// pixel is the same bits whether its rays travelled in a packet or alone.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

#include "common/accel/kd_traverse.h"
#include "common/accel/trace.h"
#include "common/image/image.h"
#include "common/math/det_math.h"
#include "common/math/ray_offset.h"
#include "common/render/frame_state.h"
#include "common/render/render_kernels.h"

namespace rtc::RTC_ISA_NS {
namespace {

// A tiny scalar vector kept inside the ISA namespace (no ISA-compiled inline code leaks out).
struct V3 {
  float x = 0, y = 0, z = 0;
};
inline V3 v3(const glm::vec3& g) { return V3{g.x, g.y, g.z}; }
inline V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator*(V3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
inline V3 operator*(V3 a, V3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
inline V3 operator-(V3 a) { return {-a.x, -a.y, -a.z}; }
inline float dot(V3 a, V3 b) { return (a.x * b.x + a.y * b.y) + a.z * b.z; }
inline V3 cross(V3 a, V3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
inline float max3(V3 a) { return std::max(a.x, std::max(a.y, a.z)); }
/// Normalised, or `fallback` when the length is zero or not finite (degenerate data never
/// turns into NaN pixels).
inline V3 normalize_or(V3 a, V3 fallback) {
  const float len2 = dot(a, a);
  if (!(len2 > 0.0f) || !std::isfinite(len2)) return fallback;
  return a * (1.0f / std::sqrt(len2));
}

inline V3 offset_origin(V3 p, V3 n, float magnitude) {
  const glm::vec3 q = offset_ray_origin(glm::vec3(p.x, p.y, p.z), glm::vec3(n.x, n.y, n.z), magnitude);
  return V3{q.x, q.y, q.z};
}

struct SurfaceHit {
  V3 point;      // offset to the side the ray came from
  V3 normal;     // shading normal facing the incoming ray
  V3 geometric;  // geometric normal facing the incoming ray
  V3 view;       // unit vector towards the ray origin
  V3 dir;        // incoming ray direction (unnormalised)
  const Material* material = nullptr;
};

SurfaceHit surface_at(const FrameState& fs, V3 dir, std::uint32_t prim, float beta, float gamma) {
  const glm::uvec3 tri = fs.triangles[prim];
  const V3 a = v3(fs.positions[tri.x]), b = v3(fs.positions[tri.y]), c = v3(fs.positions[tri.z]);
  const float alpha = (1.0f - beta) - gamma;
  // The hit point from the barycentrics, not org + t dir: it lies on the triangle to within
  // a few ulps, which is what the ulp offset assumes.
  const V3 p = (a * alpha + b * beta) + c * gamma;
  V3 ng = normalize_or(cross(b - a, c - a), V3{0, 0, 1});
  if (dot(ng, dir) > 0.0f) ng = -ng;
  V3 n = ng;
  if (fs.smooth[prim]) {
    const V3 na = v3(fs.normals[tri.x]), nb = v3(fs.normals[tri.y]), nc = v3(fs.normals[tri.z]);
    n = normalize_or((na * alpha + nb * beta) + nc * gamma, ng);
    if (dot(n, dir) > 0.0f) n = -n;
  }
  const float magnitude = vertex_magnitude(fs.positions[tri.x], fs.positions[tri.y], fs.positions[tri.z]);
  return SurfaceHit{offset_origin(p, ng, magnitude), n, ng, -normalize_or(dir, V3{0, 0, 1}), dir,
                    &fs.materials[fs.material_ids[prim]]};
}

/// Per-lane results of tracing a packet one bounce deeper.
template <int N>
struct Lanes {
  V3 weight[N];  // throughput carried by each lane
  V3 color[N];   // radiance accumulated, already weighted
};

/// Rays assembled lane by lane in plain arrays, then loaded into a packet in one go.
template <int N>
struct RayLanes {
  float org[3][N] = {};
  float dir[3][N] = {};
  void set(int i, V3 o, V3 d) {
    org[0][i] = o.x;
    org[1][i] = o.y;
    org[2][i] = o.z;
    dir[0][i] = d.x;
    dir[1][i] = d.y;
    dir[2][i] = d.z;
  }
  [[nodiscard]] RayPacket<N> packet(float t_min, float t_max) const {
    RayPacket<N> p;
    for (int a = 0; a < 3; ++a) {
      p.org[a] = vfloat<N>::load(org[a]);
      p.dir[a] = vfloat<N>::load(dir[a]);
    }
    p.t_min = vfloat<N>(t_min);
    p.t_max = vfloat<N>(t_max);
    return p;
  }
};

/// First-hit data the image keeps besides colour (sample 0 only).
struct Aov {
  float depth = std::numeric_limits<float>::infinity();
  V3 normal;
};

template <int N>
void trace_radiance(const FrameState& fs, const RayPacket<N>& ray, vbool<N> active, int depth,
                    Lanes<N>& lanes, Aov* aov, TileRayCounts& counts) {
  (depth == 0 ? counts.primary : counts.reflection) += static_cast<std::uint64_t>(std::popcount(bits(active)));
  HitPacket<N> hit{ray.t_max, vfloat<N>(0.0f), vfloat<N>(0.0f), vint<N>(-1)};
  intersect<N>(fs.tree, ray, active, hit);
  float hit_t[N], hit_beta[N], hit_gamma[N], org[3][N], dir[3][N];
  std::int32_t hit_prim[N];
  hit.t.store(hit_t);
  hit.beta.store(hit_beta);
  hit.gamma.store(hit_gamma);
  hit.prim.store(hit_prim);
  for (int a = 0; a < 3; ++a) {
    ray.org[a].store(org[a]);
    ray.dir[a].store(dir[a]);
  }
  const unsigned active_lanes = bits(active);

  SurfaceHit surf[N];
  V3 local[N];
  unsigned hit_lanes = 0;
  for (int i = 0; i < N; ++i) {
    if (!((active_lanes >> i) & 1u)) continue;
    const std::int32_t prim = hit_prim[i];
    if (prim < 0) {
      lanes.color[i] = lanes.color[i] + lanes.weight[i] * v3(fs.background);
      continue;
    }
    hit_lanes |= 1u << i;
    const V3 d{dir[0][i], dir[1][i], dir[2][i]};
    surf[i] = surface_at(fs, d, static_cast<std::uint32_t>(prim), hit_beta[i], hit_gamma[i]);
    const Material& m = *surf[i].material;
    local[i] = v3(fs.ambient) * v3(m.diffuse) + v3(m.emission);
    if (aov != nullptr) {
      // The depth channel gets the distance recomputed in double (exact for grazing rays too).
      const glm::uvec3 tri = fs.triangles[static_cast<std::uint32_t>(prim)];
      aov[i].depth = refined_distance(glm::vec3(org[0][i], org[1][i], org[2][i]), glm::vec3(d.x, d.y, d.z),
                                      fs.positions[tri.x], fs.positions[tri.y], fs.positions[tri.z], hit_t[i]);
      aov[i].normal = surf[i].normal;
    }
  }
  if (hit_lanes == 0) return;

  // One packet of shadow rays per light (Wald et al. 2001, section 3).
  for (const PointLight& light : fs.lights) {
    const V3 lp = v3(light.position);
    RayLanes<N> shadow;
    unsigned want = 0;
    V3 to_light[N];
    for (int i = 0; i < N; ++i) {
      if (!((hit_lanes >> i) & 1u)) continue;
      const SurfaceHit& s = surf[i];
      const V3 d = lp - s.point;
      // Lights behind the geometric surface or the shading normal add nothing.
      if (!(dot(d, s.geometric) > 0.0f)) continue;
      to_light[i] = normalize_or(d, s.normal);
      if (!(dot(to_light[i], s.normal) > 0.0f)) continue;
      want |= 1u << i;
      shadow.set(i, s.point, d);
    }
    if (want == 0) continue;
    counts.shadow += static_cast<std::uint64_t>(std::popcount(want));
    // The light itself sits at t = 1.
    const unsigned blocked = bits(occluded<N>(fs.tree, shadow.packet(0.0f, 1.0f), vbool<N>::from_bits(want)));
    for (int i = 0; i < N; ++i) {
      if (!((want >> i) & 1u) || ((blocked >> i) & 1u)) continue;
      const SurfaceHit& s = surf[i];
      const Material& m = *s.material;
      const float n_dot_l = dot(s.normal, to_light[i]);
      V3 contrib = v3(m.diffuse) * n_dot_l;
      if (max3(v3(m.specular)) > 0.0f) {
        const V3 r = s.normal * (2.0f * n_dot_l) - to_light[i];
        const float r_dot_v = dot(r, s.view);
        if (r_dot_v > 0.0f) contrib = contrib + v3(m.specular) * det_powf(r_dot_v, m.shininess);
      }
      local[i] = local[i] + v3(light.color) * contrib;
    }
  }

  // Mirror reflections, as one packet per bounce, cut off by depth and by ray weight.
  RayLanes<N> refl;
  Lanes<N> next;
  unsigned bounce = 0;
  for (int i = 0; i < N; ++i) {
    if (!((hit_lanes >> i) & 1u)) continue;
    lanes.color[i] = lanes.color[i] + lanes.weight[i] * local[i];
    const SurfaceHit& s = surf[i];
    const Material& m = *s.material;
    if (!m.reflective || depth >= fs.settings.max_depth) continue;
    const V3 w = lanes.weight[i] * v3(m.specular);
    if (!(max3(w) >= fs.settings.min_weight) || !(max3(w) > 0.0f)) continue;
    const V3 d = s.dir;
    V3 r = d - s.normal * (2.0f * dot(d, s.normal));
    // An interpolated normal can send the mirror ray below the surface; use the true one then.
    if (!(dot(r, s.geometric) > 0.0f)) r = d - s.geometric * (2.0f * dot(d, s.geometric));
    bounce |= 1u << i;
    next.weight[i] = w;
    next.color[i] = V3{};
    refl.set(i, s.point, r);
  }
  if (bounce == 0) return;
  trace_radiance<N>(fs, refl.packet(0.0f, std::numeric_limits<float>::infinity()), vbool<N>::from_bits(bounce),
                    depth + 1, next, nullptr, counts);
  for (int i = 0; i < N; ++i) {
    if ((bounce >> i) & 1u) lanes.color[i] = lanes.color[i] + next.color[i];
  }
}

// Sample positions inside a pixel: sample 0 is the centre (CAMERA.md), later ones follow the
// R2 low-discrepancy sequence. Computed in double from the sample index only.
inline void sample_offset(int s, double& sx, double& sy) {
  constexpr double kA1 = 0.7548776662466927, kA2 = 0.5698402909980532;
  sx = std::fmod(0.5 + kA1 * s, 1.0);
  sy = std::fmod(0.5 + kA2 * s, 1.0);
}

// Packets of 2x2 pixels when N = 4, single pixels when N = 1.
template <int N>
void render_tile_impl(const FrameState& fs, int x0, int y0, int w, int h, Image& out, TileRayCounts& counts) {
  constexpr int kBlockW = N == 1 ? 1 : 2;
  constexpr int kBlockH = N == 1 ? 1 : N / 2;
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
      V3 sum[N];
      Aov aov[N];
      for (int s = 0; s < spp; ++s) {
        double sx, sy;
        sample_offset(s, sx, sy);
        RayLanes<N> primary;
        for (int i = 0; i < N; ++i) {
          if (!((valid >> i) & 1u)) continue;
          const Ray r = fs.camera_rays.ray(x0 + px[i], y0 + py[i], sx, sy);
          primary.set(i, v3(r.origin), v3(r.dir));
        }
        const RayPacket<N> ray = primary.packet(0.0f, std::numeric_limits<float>::infinity());
        Lanes<N> lanes;
        for (int i = 0; i < N; ++i) lanes.weight[i] = V3{1, 1, 1};
        trace_radiance<N>(fs, ray, vbool<N>::from_bits(valid), 0, lanes, s == 0 ? aov : nullptr, counts);
        for (int i = 0; i < N; ++i) sum[i] = sum[i] + lanes.color[i];
      }
      const float inv_spp = 1.0f / static_cast<float>(spp);
      for (int i = 0; i < N; ++i) {
        if (!((valid >> i) & 1u)) continue;
        float* p = out.pixel(px[i], py[i]);
        const V3 c = spp == 1 ? sum[i] : sum[i] * inv_spp;
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
                       TileRayCounts& counts) {
  if (packets) {
    render_tile_impl<4>(fs, x0, y0, w, h, out, counts);
  } else {
    render_tile_impl<1>(fs, x0, y0, w, h, out, counts);
  }
}

}  // namespace

const RenderKernels& render_kernels_for_isa() {
  static const RenderKernels kernels{Isa::RTC_ISA_ENUM, &render_tile_entry};
  return kernels;
}

}  // namespace rtc::RTC_ISA_NS
