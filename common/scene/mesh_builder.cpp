// MeshBuilder: input-order numbering, degenerate dropping and the final checks of a mesh.
#include "common/scene/mesh_builder.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "common/base/error.h"
#include "common/base/log.h"
#include "common/math/unit_vector.h"

namespace rtc {

bool is_degenerate(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 n = glm::cross(b - a, c - a);
  return n.x == 0.0f && n.y == 0.0f && n.z == 0.0f;
}

MeshBuilder::MeshBuilder(std::string name, std::string source) {
  mesh_.name = std::move(name);
  mesh_.source = std::move(source);
}

std::uint32_t MeshBuilder::add_vertex(const glm::vec3& position) {
  if (mesh_.positions.size() >= std::numeric_limits<std::uint32_t>::max()) {
    throw_at(mesh_.source, 0, "more than 2^32-1 vertices");
  }
  mesh_.positions.push_back(position);
  if (has_normals_) mesh_.normals.emplace_back(0.0f);
  return static_cast<std::uint32_t>(mesh_.positions.size() - 1);
}

namespace {

/// `n` normalised, or zero ("no normal") for a zero or non-finite one. A length whose square a
/// float cannot hold (a normal longer than about 1.8e19 or shorter than about 1.1e-19, which the
/// file formats allow) is taken in double instead of losing the normal.
glm::vec3 unit_or_zero(const glm::vec3& n) {
  const float length2 = glm::dot(n, n);
  return normal_float_length2(length2) ? n / std::sqrt(length2) : unit_in_double_or(n, glm::vec3(0.0f));
}

}  // namespace

std::uint32_t MeshBuilder::add_vertex(const glm::vec3& position, const glm::vec3& normal) {
  if (mesh_.positions.size() >= std::numeric_limits<std::uint32_t>::max()) {
    throw_at(mesh_.source, 0, "more than 2^32-1 vertices");
  }
  if (!has_normals_) {
    // Vertices added before the first normal get "no normal".
    mesh_.normals.assign(mesh_.positions.size(), glm::vec3(0.0f));
    has_normals_ = true;
  }
  mesh_.normals.push_back(unit_or_zero(normal));
  mesh_.positions.push_back(position);
  return static_cast<std::uint32_t>(mesh_.positions.size() - 1);
}

std::uint32_t MeshBuilder::add_vertices(const void* packed_xyz, std::size_t count) {
  const std::size_t first = mesh_.positions.size();
  if (count >= std::numeric_limits<std::uint32_t>::max() - first) {
    throw_at(mesh_.source, 0, "more than 2^32-1 vertices");
  }
  mesh_.positions.resize(first + count);
  if (count > 0) std::memcpy(mesh_.positions.data() + first, packed_xyz, count * sizeof(glm::vec3));
  if (has_normals_) mesh_.normals.resize(first + count, glm::vec3(0.0f));
  return static_cast<std::uint32_t>(first);
}

void MeshBuilder::add_triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  RTC_DCHECK(a < mesh_.positions.size() && b < mesh_.positions.size() && c < mesh_.positions.size(),
             "triangle index out of range");
  if (next_source_index_ >= std::numeric_limits<std::uint32_t>::max()) {
    throw_at(mesh_.source, 0, "more than 2^32-1 triangles");
  }
  const auto source_index = static_cast<std::uint32_t>(next_source_index_++);
  if (a == b || b == c || a == c ||
      is_degenerate(mesh_.positions[a], mesh_.positions[b], mesh_.positions[c])) {
    ++mesh_.dropped_degenerate;
    return;
  }
  mesh_.triangles.emplace_back(a, b, c);
  mesh_.material_ids.push_back(material_);
  mesh_.source_index.push_back(source_index);
}

namespace {

// Grows geometrically: loaders call reserve() per primitive (a sphere, a glTF instance), and
// exact reservations would reallocate every time (quadratic).
template <typename T>
void reserve_more(std::vector<T>& v, std::size_t more) {
  const std::size_t needed = v.size() + more;
  if (needed > v.capacity()) v.reserve(std::max(needed, 2 * v.capacity()));
}

}  // namespace

void MeshBuilder::reserve(std::size_t vertices, std::size_t triangles) {
  reserve_more(mesh_.positions, vertices);
  if (has_normals_) reserve_more(mesh_.normals, vertices);
  reserve_more(mesh_.triangles, triangles);
  reserve_more(mesh_.material_ids, triangles);
  reserve_more(mesh_.source_index, triangles);
}

Mesh MeshBuilder::finish() {
  if (next_source_index_ == 0) throw_at(mesh_.source, 0, "no triangles in the mesh");
  if (mesh_.triangles.empty()) {
    throw_at(mesh_.source, 0,
             "all " + std::to_string(next_source_index_) +
                 " triangles are degenerate (zero area or repeated index)");
  }
  if (mesh_.dropped_degenerate > 0) {
    spdlog::warn("{}: dropped {} degenerate triangle(s) of {} (zero area or repeated index)",
                 mesh_.source, mesh_.dropped_degenerate, next_source_index_);
  }
  return std::move(mesh_);
}

}  // namespace rtc
