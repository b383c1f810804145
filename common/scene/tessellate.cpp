// Cube-spheres, open cones and polygon triangulation for the NFF loader and the default scene.
// Angles go through det_math: the same triangles on every CPU.
#include "common/scene/tessellate.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>

#include "common/base/error.h"
#include "common/math/det_math.h"

namespace rtc {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kFloatMax = std::numeric_limits<float>::max();

struct Projected {
  std::vector<glm::dvec2> points;
  double area2 = 0.0;  // twice the signed area of the projection
};

/// Projects onto the coordinate plane most parallel to the polygon (Newell normal).
Projected project(std::span<const glm::vec3> polygon) {
  glm::dvec3 normal(0.0);
  const std::size_t n = polygon.size();
  for (std::size_t i = 0; i < n; ++i) {
    const glm::dvec3 a(polygon[i]);
    const glm::dvec3 b(polygon[(i + 1) % n]);
    normal.x += (a.y - b.y) * (a.z + b.z);
    normal.y += (a.z - b.z) * (a.x + b.x);
    normal.z += (a.x - b.x) * (a.y + b.y);
  }
  const glm::dvec3 magnitude = glm::abs(normal);
  int drop = 2;
  if (magnitude.x >= magnitude.y && magnitude.x >= magnitude.z) {
    drop = 0;
  } else if (magnitude.y >= magnitude.z) {
    drop = 1;
  }
  const int u = (drop + 1) % 3;
  const int v = (drop + 2) % 3;
  Projected out;
  out.points.reserve(n);
  for (const glm::vec3& p : polygon) out.points.emplace_back(p[u], p[v]);
  for (std::size_t i = 0; i < n; ++i) {
    const glm::dvec2& a = out.points[i];
    const glm::dvec2& b = out.points[(i + 1) % n];
    out.area2 += a.x * b.y - b.x * a.y;
  }
  return out;
}

double cross2(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
  return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

bool convex_projected(const Projected& poly) {
  const std::size_t n = poly.points.size();
  if (n < 4 || poly.area2 == 0.0) return true;
  const double sign = poly.area2 > 0.0 ? 1.0 : -1.0;
  int direction_changes = 0;
  double last_dx = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const glm::dvec2& a = poly.points[(i + n - 1) % n];
    const glm::dvec2& b = poly.points[i];
    const glm::dvec2& c = poly.points[(i + 1) % n];
    if (sign * cross2(a, b, c) < 0.0) return false;
    // A star polygon turns one way everywhere but winds twice: its x direction changes more
    // than twice around the loop.
    const double dx = c.x - b.x;
    if (dx != 0.0) {
      if (last_dx != 0.0 && (dx > 0.0) != (last_dx > 0.0)) ++direction_changes;
      last_dx = dx;
    }
  }
  return direction_changes <= 2;
}

bool inside_triangle(const glm::dvec2& p, const glm::dvec2& a, const glm::dvec2& b,
                     const glm::dvec2& c, double sign) {
  return sign * cross2(a, b, p) >= 0.0 && sign * cross2(b, c, p) >= 0.0 &&
         sign * cross2(c, a, p) >= 0.0;
}

}  // namespace

bool is_convex_polygon(std::span<const glm::vec3> polygon) {
  return convex_projected(project(polygon));
}

std::vector<glm::uvec3> triangulate_polygon(std::span<const glm::vec3> polygon) {
  const auto n = static_cast<std::uint32_t>(polygon.size());
  std::vector<glm::uvec3> out;
  if (n < 3) return out;
  out.reserve(n - 2);
  const Projected poly = project(polygon);
  if (convex_projected(poly)) {
    for (std::uint32_t k = 1; k + 1 < n; ++k) out.emplace_back(0u, k, k + 1);
    return out;
  }
  // Ear clipping on a doubly linked ring, walking on from the last ear (O(n^2) worst case).
  const double sign = poly.area2 > 0.0 ? 1.0 : -1.0;
  const std::vector<glm::dvec2>& p = poly.points;
  std::vector<std::uint32_t> prev(n), next(n);
  for (std::uint32_t i = 0; i < n; ++i) {
    prev[i] = (i + n - 1) % n;
    next[i] = (i + 1) % n;
  }
  std::uint32_t count = n;
  std::uint32_t i = 0;
  std::uint32_t misses = 0;
  while (count > 3) {
    const std::uint32_t a = prev[i];
    const std::uint32_t c = next[i];
    bool ear = sign * cross2(p[a], p[i], p[c]) > 0.0;
    for (std::uint32_t j = next[c]; ear && j != a; j = next[j]) {
      // Vertices that coincide with a corner (bridged holes, touching points) do not block.
      if (p[j] == p[a] || p[j] == p[i] || p[j] == p[c]) continue;
      if (inside_triangle(p[j], p[a], p[i], p[c], sign)) ear = false;
    }
    // A full lap without an ear means the polygon is self-intersecting or degenerate:
    // clip anyway so the count stays size() - 2.
    if (ear || misses > count) {
      out.emplace_back(a, i, c);
      next[a] = c;
      prev[c] = a;
      --count;
      misses = 0;
      i = c;
    } else {
      ++misses;
      i = c;
    }
  }
  out.emplace_back(prev[i], i, next[i]);
  return out;
}

SphereTemplate make_cube_sphere(int quads) {
  RTC_CHECK(quads >= 1, "make_cube_sphere: quads must be >= 1");
  SphereTemplate out;
  const int n = quads;
  std::map<std::array<int, 3>, std::uint32_t> index_of;
  auto vertex = [&](const std::array<int, 3>& lattice) {
    const auto [it, inserted] = index_of.try_emplace(lattice, 0u);
    if (inserted) {
      it->second = static_cast<std::uint32_t>(out.points.size());
      glm::dvec3 q;
      for (int a = 0; a < 3; ++a) q[a] = det_tan(kPi / 4.0 * lattice[a] / n);
      out.points.push_back(glm::normalize(q));
    }
    return it->second;
  };
  for (int axis = 0; axis < 3; ++axis) {
    for (const int side : {1, -1}) {
      // (u, v, outward normal) right-handed, so quads wind counter-clockwise from outside.
      int u = (axis + 1) % 3;
      int v = (axis + 2) % 3;
      if (side < 0) std::swap(u, v);
      for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
          auto corner = [&](int di, int dj) {
            std::array<int, 3> lattice{};
            lattice[axis] = side * n;
            lattice[u] = 2 * (i + di) - n;
            lattice[v] = 2 * (j + dj) - n;
            return vertex(lattice);
          };
          const std::uint32_t v00 = corner(0, 0), v10 = corner(1, 0);
          const std::uint32_t v11 = corner(1, 1), v01 = corner(0, 1);
          out.triangles.emplace_back(v00, v10, v11);
          out.triangles.emplace_back(v00, v11, v01);
        }
      }
    }
  }
  return out;
}

void append_sphere(MeshBuilder& builder, const SphereTemplate& unit, const glm::dvec3& center,
                   double radius) {
  const std::uint32_t first = builder.vertex_count();
  builder.reserve(unit.points.size(), unit.triangles.size());
  for (const glm::dvec3& q : unit.points) {
    builder.add_vertex(glm::vec3(center + radius * q), glm::vec3(q));
  }
  for (const glm::uvec3& t : unit.triangles)
    builder.add_triangle(first + t.x, first + t.y, first + t.z);
}

void append_cone(MeshBuilder& builder, const glm::dvec3& base, double base_radius,
                 const glm::dvec3& apex, double apex_radius, int segments) {
  RTC_CHECK(segments >= 3, "append_cone: segments must be >= 3");
  const glm::dvec3 axis = apex - base;
  const double height = glm::length(axis);
  // A zero-length axis still gets its 2 * segments (degenerate, dropped) triangles, so
  // triangle numbering does not depend on the data.
  const glm::dvec3 w = height > 0.0 ? axis / height : glm::dvec3(0.0, 0.0, 1.0);
  const glm::dvec3 helper =
      std::abs(w.x) < 0.9 ? glm::dvec3(1.0, 0.0, 0.0) : glm::dvec3(0.0, 1.0, 0.0);
  const glm::dvec3 u = glm::normalize(glm::cross(w, helper));
  const glm::dvec3 v = glm::cross(w, u);
  const std::uint32_t first = builder.vertex_count();
  const auto m = static_cast<std::uint32_t>(segments);
  builder.reserve(2 * m, 2 * m);
  for (int ring = 0; ring < 2; ++ring) {
    const glm::dvec3& center = ring == 0 ? base : apex;
    const double radius = ring == 0 ? base_radius : apex_radius;
    for (std::uint32_t k = 0; k < m; ++k) {
      const double angle = 2.0 * kPi * k / m;
      const glm::dvec3 radial = det_cos(angle) * u + det_sin(angle) * v;
      glm::dvec3 normal = radial * height + w * (base_radius - apex_radius);
      // A cone spanning most of the float range has a normal beyond it; only its direction
      // matters (the builder normalises), and converting it as it is would be undefined.
      const double largest = std::max({std::abs(normal.x), std::abs(normal.y), std::abs(normal.z)});
      if (largest > kFloatMax) normal /= largest;
      builder.add_vertex(glm::vec3(center + radius * radial), glm::vec3(normal));
    }
  }
  for (std::uint32_t k = 0; k < m; ++k) {
    const std::uint32_t b0 = first + k, b1 = first + (k + 1) % m;
    const std::uint32_t a0 = b0 + m, a1 = b1 + m;
    builder.add_triangle(b0, b1, a1);
    builder.add_triangle(b0, a1, a0);
  }
}

}  // namespace rtc
