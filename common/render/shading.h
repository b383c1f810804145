// Scalar shading geometry shared by the tile kernels and the benchmarks: the surface at a hit
// and the shadow ray towards a light, computed the same way (same operations, same order)
// wherever they are needed.
#pragma once

#include <cmath>
#include <cstdint>
#include <optional>

#include <glm/glm.hpp>

#include "common/accel/trace.h"
#include "common/math/ray_offset.h"
#include "common/math/unit_vector.h"
#include "common/render/frame_state.h"

namespace rtc {

/// The surface where a ray hit triangle `prim` at barycentrics (beta, gamma).
struct SurfaceSample {
  glm::vec3 point{0.0f};      ///< hit point offset off the surface towards the incoming ray
  glm::vec3 normal{0.0f};     ///< unit shading normal facing the incoming ray
  glm::vec3 geometric{0.0f};  ///< unit geometric normal facing the incoming ray
  glm::vec3 view{0.0f};       ///< unit vector back along the incoming ray
  glm::vec3 dir{0.0f};        ///< the incoming ray's direction (as given)
  const Material* material = nullptr;
};

/// Hit point interpolated from the barycentrics (not org + t dir), normals faced towards the
/// ray (triangles are double sided), and the point offset along the geometric normal by
/// offset_ray_origin (common/math/ray_offset.h). Never NaN: degenerate normals fall back to
/// the geometric one. (Defined below, inline.)
[[nodiscard]] inline SurfaceSample surface_at(const FrameState& fs, const glm::vec3& dir, std::uint32_t prim,
                                              float beta, float gamma);

/// surface_at(fs, dir, prim, beta, gamma).normal alone (the same bits), for kernels that need
/// nothing else of the surface. (Defined below, inline.)
[[nodiscard]] inline glm::vec3 shading_normal_at(const FrameState& fs, const glm::vec3& dir, std::uint32_t prim,
                                                 float beta, float gamma);

/// A shadow ray from a surface to a point light: origin = the offset hit point, dir = light -
/// origin, t in (0, 1). `to_light` is the unit direction used for shading.
struct ShadowRay {
  RayQuery ray;
  glm::vec3 to_light{0.0f};
};

/// Empty when the light is behind the geometric surface or the shading normal (it adds nothing).
/// (Defined below, inline.)
[[nodiscard]] inline std::optional<ShadowRay> shadow_ray(const SurfaceSample& s, const PointLight& light);
/// The same ray in parts, for the tile kernels: false when shadow_ray is empty; otherwise the
/// ray is (s.point, t_min 0, d, t_max 1) and to_light its normalised direction. (The kernels
/// write the parts straight into their packets: copying the returned struct went through
/// vector moves of fields just stored one by one, a store-forwarding stall per lane and light.)
inline bool shadow_ray_parts(const SurfaceSample& s, const PointLight& light, glm::vec3& d, glm::vec3& to_light);

// ---- definitions (inline so that each ISA's tile kernel compiles them in) ----

namespace shading_detail {

/// Normalised, or `fallback` when the length is zero or not finite. A far light (1e20 away, a
/// directional light's usual stand-in) or a huge or tiny triangle's normal keeps its direction.
inline glm::vec3 normalize_or(const glm::vec3& a, const glm::vec3& fallback) {
  const float len2 = glm::dot(a, a);
  if (!normal_float_length2(len2)) return unit_in_double_or(a, fallback);
  return a * (1.0f / std::sqrt(len2));
}

/// unit_normal for a triangle whose normal's squared length a float cannot hold: the cross
/// product in double. Rare, so out of line.
[[gnu::cold, gnu::noinline]] inline glm::vec3 unit_normal_in_double(const glm::vec3& e1, const glm::vec3& e2) {
  return unit_rounded_or(glm::cross(glm::dvec3(e1), glm::dvec3(e2)), glm::vec3(0, 0, 1));
}

/// The unit normal of triangle (a, b, c), or +z for one of zero area. The cross product of
/// edges longer than about 4e9 overflows a float, and of edges shorter than about 1e-10
/// underflows (loses bits); those go through double.
inline glm::vec3 unit_normal(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 e1 = b - a, e2 = c - a;
  const glm::vec3 n = glm::cross(e1, e2);
  const float len2 = glm::dot(n, n);
  if (!normal_float_length2(len2)) return unit_normal_in_double(e1, e2);
  return n * (1.0f / std::sqrt(len2));
}

/// The geometric and shading normals at barycentrics (beta, gamma) of triangle `prim`, both
/// faced towards the ray.
struct Normals {
  glm::vec3 geometric;
  glm::vec3 shading;
};

inline Normals normals_at(const FrameGeometry& g, const glm::uvec3& tri, const glm::vec3& a, const glm::vec3& b,
                   const glm::vec3& c, const glm::vec3& dir, std::uint32_t prim, float alpha, float beta, float gamma) {
  glm::vec3 ng = unit_normal(a, b, c);
  if (glm::dot(ng, dir) > 0.0f) ng = -ng;
  glm::vec3 n = ng;
  if (g.smooth[prim]) {
    const glm::vec3 na = g.normals[tri.x], nb = g.normals[tri.y], nc = g.normals[tri.z];
    n = normalize_or((na * alpha + nb * beta) + nc * gamma, ng);
    if (glm::dot(n, dir) > 0.0f) n = -n;
  }
  return Normals{ng, n};
}

}  // namespace shading_detail

inline SurfaceSample surface_at(const FrameState& fs, const glm::vec3& dir, std::uint32_t prim, float beta, float gamma) {
  const FrameGeometry& g = *fs.geometry;
  const glm::uvec3 tri = g.triangles[prim];
  const glm::vec3 a = g.positions[tri.x], b = g.positions[tri.y], c = g.positions[tri.z];
  const float alpha = (1.0f - beta) - gamma;
  const glm::vec3 p = (a * alpha + b * beta) + c * gamma;
  const shading_detail::Normals n = shading_detail::normals_at(g, tri, a, b, c, dir, prim, alpha, beta, gamma);
  SurfaceSample s;
  s.point = offset_ray_origin(p, n.geometric, vertex_magnitude(a, b, c));
  s.normal = n.shading;
  s.geometric = n.geometric;
  s.view = -shading_detail::normalize_or(dir, glm::vec3(0, 0, 1));
  s.dir = dir;
  s.material = &fs.materials[g.material_ids[prim]];
  return s;
}

inline glm::vec3 shading_normal_at(const FrameState& fs, const glm::vec3& dir, std::uint32_t prim, float beta, float gamma) {
  const FrameGeometry& g = *fs.geometry;
  const glm::uvec3 tri = g.triangles[prim];
  const glm::vec3 a = g.positions[tri.x], b = g.positions[tri.y], c = g.positions[tri.z];
  const float alpha = (1.0f - beta) - gamma;
  return shading_detail::normals_at(g, tri, a, b, c, dir, prim, alpha, beta, gamma).shading;
}

/// Inline: the tile kernels call it per lane and light, and out of line each call waited on its
/// own square root and division (6% of a frame's profile); inlined, the lanes' overlap. The
/// same operations in the same order at every ISA (no FMA contraction), so the same bits.
inline bool shadow_ray_parts(const SurfaceSample& s, const PointLight& light, glm::vec3& d, glm::vec3& to_light) {
  d = light.position - s.point;
  if (!(glm::dot(d, s.geometric) > 0.0f)) return false;
  to_light = shading_detail::normalize_or(d, s.normal);
  return glm::dot(to_light, s.normal) > 0.0f;
}

inline std::optional<ShadowRay> shadow_ray(const SurfaceSample& s, const PointLight& light) {
  glm::vec3 d, to_light;
  if (!shadow_ray_parts(s, light, d, to_light)) return std::nullopt;
  // The light itself sits at t = 1.
  return ShadowRay{RayQuery{s.point, 0.0f, d, 1.0f}, to_light};
}

}  // namespace rtc
