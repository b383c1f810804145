// Collects one mesh's vertices and triangles for the loaders: numbers triangles in input
// order, drops degenerate ones and checks the result.
#pragma once

#include <cstdint>
#include <string>

#include <glm/glm.hpp>

#include "common/scene/scene.h"

namespace rtc {

/// True when the triangle has a repeated index or zero area in float32 (the cross product of
/// its edges is exactly zero), the rule the scene pack used when it counted degenerates.
[[nodiscard]] bool is_degenerate(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);

/// Builds a Mesh. Vertices may carry a normal or not; when any does, the mesh gets one normal
/// per position and vertices without one get (0, 0, 0) ("use the geometric normal").
/// Not thread-safe; one builder per file.
class MeshBuilder {
 public:
  /// `source` names the file in messages and becomes Mesh::source.
  MeshBuilder(std::string name, std::string source);

  /// Appends a vertex (position must be finite: loaders check and report with a line).
  std::uint32_t add_vertex(const glm::vec3& position);
  /// Appends a vertex with a shading normal (normalised here unless zero).
  std::uint32_t add_vertex(const glm::vec3& position, const glm::vec3& normal);
  /// Appends `count` positions stored as packed float x, y, z (12 bytes each, host byte
  /// order, need not be aligned), without normals; returns the first one's index.
  std::uint32_t add_vertices(const void* packed_xyz, std::size_t count);
  [[nodiscard]] std::uint32_t vertex_count() const {
    return static_cast<std::uint32_t>(mesh_.positions.size());
  }
  [[nodiscard]] const glm::vec3& position(std::uint32_t i) const { return mesh_.positions[i]; }

  /// Appends a triangle with the current material; indices must be < vertex_count() (the
  /// loader checks untrusted indices first). Degenerate triangles take a source index and are
  /// counted, not stored.
  void add_triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c);
  void set_material(std::uint32_t material_id) { material_ = material_id; }
  /// Reserves room for about `vertices` and `triangles` more.
  void reserve(std::size_t vertices, std::size_t triangles);

  /// Triangles seen so far, degenerate ones included.
  [[nodiscard]] std::uint64_t input_triangles() const { return next_source_index_; }

  /// Returns the mesh; throws rtc::Error("<source>: ...") when it has no triangles or every
  /// triangle is degenerate, or when the triangle count does not fit 32-bit ids. Logs one
  /// warning with the number of dropped degenerate triangles.
  [[nodiscard]] Mesh finish();

 private:
  Mesh mesh_;
  std::uint32_t material_ = 0;
  std::uint64_t next_source_index_ = 0;
  bool has_normals_ = false;
};

}  // namespace rtc
