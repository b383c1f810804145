// One frame of a scene, ready to trace: world-space geometry, kd-tree, camera, lights.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "common/accel/kd_tree.h"
#include "common/math/camera.h"
#include "common/scene/scene.h"

namespace rtc {

/// Everything a tile render of one frame reads. Immutable once built; share it between
/// threads freely. Shading data (normals, materials) are kept apart from the 48-byte
/// triangle records in the tree and touched only for hits.
struct FrameState {
  int frame = 0;
  int width = 0, height = 0;
  Camera camera;
  CameraRays camera_rays{Camera{}, 1, 1};
  std::vector<glm::vec3> positions;        ///< world space
  std::vector<glm::vec3> normals;          ///< world space, one per position (zero when none)
  std::vector<glm::uvec3> triangles;       ///< into positions
  std::vector<std::uint32_t> material_ids; ///< per triangle
  std::vector<std::uint8_t> smooth;        ///< per triangle: 1 = interpolate vertex normals
  std::vector<std::uint32_t> source_index; ///< per triangle: id in input-file order (all meshes)
  std::vector<Material> materials;
  std::vector<PointLight> lights;          ///< world space
  glm::vec3 background{0.0f};
  glm::vec3 ambient{0.0f};
  RenderSettings settings;
  KdTree tree;
};

}  // namespace rtc
