// load_scene: scene JSON or a bare mesh file, and the automatic framing for bare meshes.
#include "common/scene/load.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include <fmt/format.h>

#include "common/base/error.h"
#include "common/base/log.h"
#include "common/math/det_math.h"
#include "common/math/unit_vector.h"
#include "common/scene/load_internal.h"
#include "common/scene/mesh_file.h"

namespace rtc {

std::uint32_t append_mesh(Scene& scene, Mesh mesh, const std::vector<Material>& materials) {
  if (scene.materials.empty()) scene.materials.emplace_back();
  std::vector<std::uint32_t> remap(materials.size());
  for (std::size_t i = 0; i < materials.size(); ++i) {
    const auto it = std::find(scene.materials.begin(), scene.materials.end(), materials[i]);
    remap[i] = static_cast<std::uint32_t>(it - scene.materials.begin());
    if (it == scene.materials.end()) scene.materials.push_back(materials[i]);
  }
  for (std::uint32_t& id : mesh.material_ids) {
    RTC_CHECK(id < remap.size(), "mesh material id outside its file's materials");
    id = remap[id];
  }
  scene.meshes.push_back(std::move(mesh));
  return static_cast<std::uint32_t>(scene.meshes.size() - 1);
}

namespace {

/// Whether every coordinate of `p` fits a float (a NaN does not).
bool in_float_range(const glm::dvec3& p) {
  const double float_max = std::numeric_limits<float>::max();
  return std::abs(p.x) <= float_max && std::abs(p.y) <= float_max && std::abs(p.z) <= float_max;
}

/// How the automatic camera's and light's errors name the scene: its file, else its name.
std::string named(const Scene& scene) { return scene.source.empty() ? scene.name : scene.source.string(); }

}  // namespace

void place_auto_camera(Scene& scene) {
  const Aabb box = scene.bounds();
  glm::dvec3 center(0.0);
  double radius = 1.0;
  if (!box.empty()) {
    // In double: hi - lo in float overflows for boxes spanning more than the float range.
    center = 0.5 * (glm::dvec3(box.lo) + glm::dvec3(box.hi));
    radius = 0.5 * glm::length(glm::dvec3(box.hi) - glm::dvec3(box.lo));
    if (!(radius > 0.0)) radius = 1.0;
  }
  constexpr double kVfovDeg = 45.0;
  constexpr double kPi = 3.14159265358979323846;
  // The bounding sphere must fit the narrower of the two fields of view.
  const double aspect = static_cast<double>(scene.width) / static_cast<double>(scene.height);
  const double half_v = kVfovDeg * kPi / 360.0;
  const double half_h = det_atan2(det_tan(half_v) * aspect, 1.0);
  const double half = std::min(half_v, half_h);
  const double distance = 1.05 * radius / det_sin(half);  // 5 % margin
  const glm::dvec3 direction = glm::normalize(glm::dvec3(0.4, 0.6, 1.0));
  const glm::dvec3 eye = center + distance * direction;
  if (!in_float_range(eye)) {
    throw Error(fmt::format("{}: the scene is too large for the automatic camera (bounding "
                            "radius {:.3g}); give a camera",
                            named(scene), radius));
  }
  scene.camera.eye = glm::vec3(eye);
  scene.camera.look_at = glm::vec3(center);
  scene.camera.up = glm::vec3(0.0f, 1.0f, 0.0f);
  scene.camera.vfov_deg = static_cast<float>(kVfovDeg);
  scene.camera_automatic = true;
}

void place_default_light(Scene& scene) {
  // In float, as always, where that holds the numbers; in double, rounded once, for a camera so
  // far from its target (beyond about 1.8e19, where a float squared length overflows, or so
  // near that it underflows) that float would give a NaN light.
  const glm::vec3 view = scene.camera.eye - scene.camera.look_at;
  const float distance2 = glm::dot(view, view);
  if (normal_float_length2(distance2)) {
    const float distance = glm::length(view);
    const glm::vec3 up = glm::normalize(scene.camera.up);
    glm::vec3 side = glm::cross(view, up);
    const float side_length = glm::length(side);
    side = side_length > 0.0f ? side / side_length : glm::vec3(1.0f, 0.0f, 0.0f);
    const glm::vec3 position = scene.camera.eye + 0.5f * distance * up + 0.25f * distance * side;
    if (std::isfinite(position.x) && std::isfinite(position.y) && std::isfinite(position.z)) {
      scene.lights.push_back(PointLight{position, glm::vec3(1.0f)});
      return;
    }
  }
  const glm::dvec3 eye(scene.camera.eye);
  const glm::dvec3 dview = eye - glm::dvec3(scene.camera.look_at);
  const double distance = glm::length(dview);
  const glm::dvec3 up = glm::normalize(glm::dvec3(scene.camera.up));
  glm::dvec3 side = glm::cross(dview, up);
  const double side_length = glm::length(side);
  side = side_length > 0.0 ? side / side_length : glm::dvec3(1.0, 0.0, 0.0);
  const glm::dvec3 position = eye + 0.5 * distance * up + 0.25 * distance * side;
  if (!in_float_range(position)) {
    throw Error(fmt::format("{}: the automatic light would lie outside the float range (the camera is "
                            "{:.3g} from its target); give a light",
                            named(scene), distance));
  }
  scene.lights.push_back(PointLight{glm::vec3(position), glm::vec3(1.0f)});
}

void frame_automatically(Scene& scene) {
  place_auto_camera(scene);
  if (scene.lights.empty()) place_default_light(scene);
}

void set_resolution(Scene& scene, int width, int height) {
  if (width <= 0 || height <= 0) {
    throw Error(fmt::format("resolution must be positive, got {}x{}", width, height));
  }
  scene.width = width;
  scene.height = height;
  // An automatic camera was fitted to the old aspect ratio; fit it to the new one so nothing
  // is cropped. A camera from the scene file stays as it is.
  if (scene.camera_automatic) place_auto_camera(scene);
}

Scene load_scene(const std::filesystem::path& path) {
  // A scene pack's folder (../shared/scenes/NAME) stands for the view.json inside it.
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    const std::filesystem::path view = path / "view.json";
    if (!std::filesystem::exists(view, ec)) {
      throw Error(path.string() + ": is a folder without a view.json; give a scene or mesh file");
    }
    return load_scene_json(view);
  }
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".json") return load_scene_json(path);

  MeshFile file = load_mesh_file(path);
  Scene scene;
  scene.name = path.stem().string();
  scene.source = path;
  scene.materials.emplace_back();
  append_mesh(scene, std::move(file.mesh), file.materials);
  if (file.resolution) {
    scene.width = file.resolution->x;
    scene.height = file.resolution->y;
  }
  if (file.background) scene.background = *file.background;
  scene.lights = std::move(file.lights);
  if (file.camera) {
    scene.camera = *file.camera;
  } else {
    place_auto_camera(scene);
  }
  if (scene.lights.empty()) place_default_light(scene);
  spdlog::info("{}: {} triangles, {} materials", path.string(), scene.triangle_count(),
               scene.materials.size());
  return scene;
}

}  // namespace rtc
