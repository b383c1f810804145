// Surface geometry at a hit and shadow rays (scalar, compiled once, shared by all ISAs).
#include "common/render/shading.h"

#include <cmath>

#include "common/math/ray_offset.h"

namespace rtc {
namespace {

/// Normalised, or `fallback` when the length is zero or not finite.
glm::vec3 normalize_or(const glm::vec3& a, const glm::vec3& fallback) {
  const float len2 = glm::dot(a, a);
  if (!(len2 > 0.0f) || !std::isfinite(len2)) return fallback;
  return a * (1.0f / std::sqrt(len2));
}

/// The geometric and shading normals at barycentrics (beta, gamma) of triangle `prim`, both
/// faced towards the ray.
struct Normals {
  glm::vec3 geometric;
  glm::vec3 shading;
};

Normals normals_at(const FrameGeometry& g, const glm::uvec3& tri, const glm::vec3& a, const glm::vec3& b,
                   const glm::vec3& c, const glm::vec3& dir, std::uint32_t prim, float alpha, float beta, float gamma) {
  glm::vec3 ng = normalize_or(glm::cross(b - a, c - a), glm::vec3(0, 0, 1));
  if (glm::dot(ng, dir) > 0.0f) ng = -ng;
  glm::vec3 n = ng;
  if (g.smooth[prim]) {
    const glm::vec3 na = g.normals[tri.x], nb = g.normals[tri.y], nc = g.normals[tri.z];
    n = normalize_or((na * alpha + nb * beta) + nc * gamma, ng);
    if (glm::dot(n, dir) > 0.0f) n = -n;
  }
  return Normals{ng, n};
}

}  // namespace

SurfaceSample surface_at(const FrameState& fs, const glm::vec3& dir, std::uint32_t prim, float beta, float gamma) {
  const FrameGeometry& g = *fs.geometry;
  const glm::uvec3 tri = g.triangles[prim];
  const glm::vec3 a = g.positions[tri.x], b = g.positions[tri.y], c = g.positions[tri.z];
  const float alpha = (1.0f - beta) - gamma;
  const glm::vec3 p = (a * alpha + b * beta) + c * gamma;
  const Normals n = normals_at(g, tri, a, b, c, dir, prim, alpha, beta, gamma);
  SurfaceSample s;
  s.point = offset_ray_origin(p, n.geometric, vertex_magnitude(a, b, c));
  s.normal = n.shading;
  s.geometric = n.geometric;
  s.view = -normalize_or(dir, glm::vec3(0, 0, 1));
  s.dir = dir;
  s.material = &fs.materials[g.material_ids[prim]];
  return s;
}

glm::vec3 shading_normal_at(const FrameState& fs, const glm::vec3& dir, std::uint32_t prim, float beta, float gamma) {
  const FrameGeometry& g = *fs.geometry;
  const glm::uvec3 tri = g.triangles[prim];
  const glm::vec3 a = g.positions[tri.x], b = g.positions[tri.y], c = g.positions[tri.z];
  const float alpha = (1.0f - beta) - gamma;
  return normals_at(g, tri, a, b, c, dir, prim, alpha, beta, gamma).shading;
}


}  // namespace rtc
