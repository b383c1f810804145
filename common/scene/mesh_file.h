// Mesh file loaders: OBJ+MTL, PLY, glTF 2.0 (.gltf/.glb) and NFF (Haines SPD). Each file
// becomes one mesh with its materials; NFF also brings a view, lights and a background.
#pragma once

#include <filesystem>
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "common/scene/scene.h"

namespace rtc {

/// How NFF curved primitives become triangles. The defaults are the scene pack's level 4:
/// spheres are cube-spheres with 4x4 tan-warped quads per cube face (192 triangles),
/// cones/cylinders have 16 segments around, 1 along, no end caps (32 triangles).
struct Tessellation {
  static constexpr int kMinSphereQuads = 1;
  static constexpr int kMaxSphereQuads = 1024;
  static constexpr int kMinConeSegments = 3;
  static constexpr int kMaxConeSegments = 65536;

  int sphere_quads = 4;    ///< quads along each edge of a cube face, in [1, 1024]
  int cone_segments = 16;  ///< segments around a cone, in [3, 65536]

  bool operator==(const Tessellation&) const = default;
};

struct MeshLoadOptions {
  Tessellation tessellation;
};

/// What one mesh file brings. `mesh.material_ids` index into `materials` (never empty).
/// `camera`, `resolution`, `background` and `lights` are filled by NFF only.
struct MeshFile {
  Mesh mesh;
  std::vector<Material> materials;
  std::optional<Camera> camera;
  std::optional<glm::ivec2> resolution;
  std::optional<glm::vec3> background;
  std::vector<PointLight> lights;
};

/// Loads a mesh file by extension (case-insensitive): .obj, .ply, .gltf, .glb, .nff.
/// `.nff.gz` / `.nff.xz` are rejected with a hint to decompress them. Throws rtc::Error
/// naming the file, the line or element, and what is wrong. Thread-safe (no shared state).
[[nodiscard]] MeshFile load_mesh_file(const std::filesystem::path& path,
                                      const MeshLoadOptions& options = {});

/// Wavefront OBJ with its MTL libraries; polygons are fan-triangulated from vertex 0.
[[nodiscard]] MeshFile load_obj(const std::filesystem::path& path);
/// PLY: ascii, binary_little_endian and binary_big_endian 1.0.
[[nodiscard]] MeshFile load_ply(const std::filesystem::path& path);
/// glTF 2.0 (TinyGLTF for the container, accessor ranges checked here): node matrices and
/// instancing baked into world space; points and lines skipped; strips and fans triangulated.
[[nodiscard]] MeshFile load_gltf(const std::filesystem::path& path);
/// NFF as written by SPD 3.14 (and the three-line cone form of NFF.TXT).
[[nodiscard]] MeshFile load_nff(const std::filesystem::path& path,
                                const Tessellation& tessellation = {});

}  // namespace rtc
