// Pieces shared by the scene loaders (load.cpp, scene_json.cpp, default_scene.cpp); not a
// public interface.
#pragma once

#include <cstdint>
#include <filesystem>

#include "common/scene/mesh_file.h"
#include "common/scene/scene.h"

namespace rtc {

/// Loads the scene JSON format of docs/scene-format.md.
[[nodiscard]] Scene load_scene_json(const std::filesystem::path& path);

/// Moves `mesh` into `scene` with its materials: each material of `materials` is matched
/// against scene.materials (equal value reuses the slot, material 0 being the default) or
/// appended, and the mesh's material ids are remapped. Returns the new mesh's index.
std::uint32_t append_mesh(Scene& scene, Mesh mesh, const std::vector<Material>& materials);

/// Points `scene.camera` at scene.bounds() (vfov 45, from the +x/+y/+z side, whole bounding
/// sphere in view at scene.width x scene.height). Throws rtc::Error when the eye would lie
/// beyond the float range.
void place_auto_camera(Scene& scene);

/// Appends one white light above and beside the camera.
void place_default_light(Scene& scene);

}  // namespace rtc
