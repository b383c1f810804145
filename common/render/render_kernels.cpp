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

  SurfaceHit surf[N];
  V3 local[N];
  unsigned hit_lanes = 0;
  for (int i = 0; i < N; ++i) {
    if (!active.lane(i)) continue;
    const std::int32_t prim = hit.prim.lane(i);
    if (prim < 0) {
      lanes.color[i] = lanes.color[i] + lanes.weight[i] * v3(fs.background);
      continue;
    }
    hit_lanes |= 1u << i;
    const V3 dir{ray.dir.x.lane(i), ray.dir.y.lane(i), ray.dir.z.lane(i)};
    surf[i] = surface_at(fs, dir, static_cast<std::uint32_t>(prim), hit.beta.lane(i), hit.gamma.lane(i));
    const Material& m = *surf[i].material;
    local[i] = v3(fs.ambient) * v3(m.diffuse) + v3(m.emission);
    if (aov != nullptr) {
      // The depth channel gets the distance recomputed in double (exact for grazing rays too).
      const glm::uvec3 tri = fs.triangles[static_cast<std::uint32_t>(prim)];
      aov[i].depth = refined_distance(glm::vec3(ray.org.x.lane(i), ray.org.y.lane(i), ray.org.z.lane(i)),
                                      glm::vec3(dir.x, dir.y, dir.z), fs.positions[tri.x], fs.positions[tri.y],
                                      fs.positions[tri.z], hit.t.lane(i));
      aov[i].normal = surf[i].normal;
    }
  }
  if (hit_lanes == 0) return;

  // One packet of shadow rays per light (Wald et al. 2001, section 3).
  for (const PointLight& light : fs.lights) {
    const V3 lp = v3(light.position);
    RayPacket<N> shadow;
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
      shadow.org.x.set_lane(i, s.point.x);
      shadow.org.y.set_lane(i, s.point.y);
      shadow.org.z.set_lane(i, s.point.z);
      shadow.dir.x.set_lane(i, d.x);
      shadow.dir.y.set_lane(i, d.y);
      shadow.dir.z.set_lane(i, d.z);
    }
    if (want == 0) continue;
    counts.shadow += static_cast<std::uint64_t>(std::popcount(want));
    shadow.t_min = vfloat<N>(0.0f);
    shadow.t_max = vfloat<N>(1.0f);  // the light itself sits at t = 1
    const vbool<N> blocked = occluded<N>(fs.tree, shadow, vbool<N>::from_bits(want));
    for (int i = 0; i < N; ++i) {
      if (!((want >> i) & 1u) || blocked.lane(i)) continue;
      const SurfaceHit& s = surf[i];
      const Material& m = *s.material;
      const float n_dot_l = dot(s.normal, to_light[i]);
      V3 contrib = v3(m.diffuse) * n_dot_l;
      if (max3(v3(m.specular)) > 0.0f) {
        const V3 r = s.normal * (2.0f * n_dot_l) - to_light[i];
        const float r_dot_v = dot(r, s.view);
        if (r_dot_v > 0.0f) contrib = contrib + v3(m.specular) * std::pow(r_dot_v, m.shininess);
      }
      local[i] = local[i] + v3(light.color) * contrib;
    }
  }

  // Mirror reflections, as one packet per bounce, cut off by depth and by ray weight.
  RayPacket<N> refl;
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
    refl.org.x.set_lane(i, s.point.x);
    refl.org.y.set_lane(i, s.point.y);
    refl.org.z.set_lane(i, s.point.z);
    refl.dir.x.set_lane(i, r.x);
    refl.dir.y.set_lane(i, r.y);
    refl.dir.z.set_lane(i, r.z);
  }
  if (bounce == 0) return;
  refl.t_min = vfloat<N>(0.0f);
  refl.t_max = vfloat<N>(std::numeric_limits<float>::infinity());
  trace_radiance<N>(fs, refl, vbool<N>::from_bits(bounce), depth + 1, next, nullptr, counts);
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
        RayPacket<N> ray;
        for (int i = 0; i < N; ++i) {
          if (!((valid >> i) & 1u)) continue;
          const Ray r = fs.camera_rays.ray(x0 + px[i], y0 + py[i], sx, sy);
          ray.org.x.set_lane(i, r.origin.x);
          ray.org.y.set_lane(i, r.origin.y);
          ray.org.z.set_lane(i, r.origin.z);
          ray.dir.x.set_lane(i, r.dir.x);
          ray.dir.y.set_lane(i, r.dir.y);
          ray.dir.z.set_lane(i, r.dir.z);
        }
        ray.t_min = vfloat<N>(0.0f);
        ray.t_max = vfloat<N>(std::numeric_limits<float>::infinity());
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
