// Turning curved primitives and polygons into triangles: cube-spheres, open cones and
// cylinders, and polygon triangulation (fan when convex, ear clipping when concave).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "common/scene/mesh_builder.h"

namespace rtc {

/// True when the polygon (any plane in 3D, either winding) is convex; collinear vertices
/// are allowed. Degenerate polygons (zero area) count as convex.
[[nodiscard]] bool is_convex_polygon(std::span<const glm::vec3> polygon);

/// Triangles (indices into `polygon`) covering a simple polygon: a fan from vertex 0 when it
/// is convex, ear clipping otherwise. Keeps the polygon's winding and always returns
/// size() - 2 triangles (none for fewer than 3 vertices); a self-intersecting polygon gets
/// triangles anyway, never an endless loop.
[[nodiscard]] std::vector<glm::uvec3> triangulate_polygon(std::span<const glm::vec3> polygon);

/// A unit sphere as a cube-sphere: `quads` x `quads` quads per cube face, warped by tan so
/// the grid lines are equally spaced in angle, shared vertices welded. Triangles wind
/// counter-clockwise seen from outside; 12 * quads^2 triangles, 6 quads^2 + 2 vertices.
struct SphereTemplate {
  std::vector<glm::dvec3> points;  ///< unit length, also the normals
  std::vector<glm::uvec3> triangles;
};
[[nodiscard]] SphereTemplate make_cube_sphere(int quads);

/// Appends a sphere (vertices with normals) with the builder's current material. The caller
/// keeps |center| + radius within the float range (the NFF loader checks it per line).
void append_sphere(MeshBuilder& builder, const SphereTemplate& unit, const glm::dvec3& center,
                   double radius);

/// Appends an open cone or cylinder from a base circle to an apex circle (either radius may
/// be 0): `segments` around, 1 along, no caps, 2 * segments triangles, normals perpendicular
/// to the slanted side, winding counter-clockwise seen from outside. The caller keeps both
/// circles within the float range.
void append_cone(MeshBuilder& builder, const glm::dvec3& base, double base_radius,
                 const glm::dvec3& apex, double apex_radius, int segments);

}  // namespace rtc
