// Loading scenes: scene JSON (a superset of ../shared/scenes/*/view.json), bare mesh files,
// and the embedded default scene.
#pragma once

#include <filesystem>

#include "common/scene/scene.h"

namespace rtc {

/// Loads a scene file. `.json` is the scene format (see docs/scene-format.md); `.obj`, `.ply`,
/// `.gltf`, `.glb`, `.nff` (also `.nff.gz`/`.nff.xz` are rejected with a hint) are bare meshes
/// framed by an automatic camera and lit by a default light (NFF brings its own view and
/// lights). A folder stands for the view.json inside it (a scene pack). Throws rtc::Error naming
/// the file, line or field and the reason.
[[nodiscard]] Scene load_scene(const std::filesystem::path& path);

/// The procedural scene compiled into the program: a floor, reflective and diffuse objects,
/// two lights, a few tens of thousands of triangles. Same bits every call.
[[nodiscard]] Scene default_scene();

/// Places a camera that frames `bounds` and a default light, as used for bare mesh files.
/// Throws rtc::Error when the scene is too large for the camera to sit within float range.
void frame_automatically(Scene& scene);

/// Changes the image size; an automatically placed camera is fitted again to the new aspect
/// ratio (Scene::camera_automatic). Throws rtc::Error for a non-positive size.
void set_resolution(Scene& scene, int width, int height);

}  // namespace rtc
