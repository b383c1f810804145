// The shared scene pack (../shared/scenes): every view loads with its triangle count, and the
// NFF loader reproduces the pack's own tessellation. Skipped when the pack is absent.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

#include "common/scene/load.h"
#include "common/scene/mesh_file.h"
#include "test_files.h"

namespace rtc {
namespace {

using test::error_of;
using test::scene_pack;

struct ViewCounts {
  std::uint64_t input;  // "triangles" of the view: before dropping degenerates
  std::uint64_t kept;
};

// From the pack's README and view.json files.
const std::map<std::string, ViewCounts>& expected_views() {
  static const std::map<std::string, ViewCounts> views{
      {"bunny/view.json", {3674, 3674}},
      {"gltf-samples/view-BoxTextured.json", {12, 12}},
      {"gltf-samples/view-Wuson.json", {3732, 3732}},
      {"gltf-samples/view.json", {121496, 110336}},
      {"radiance-cabin/view.json", {262425, 262425}},
      {"radiance-office/view.json", {19968, 19968}},
      {"spd-balls-s3/view.json", {157442, 157442}},
      {"spd-balls/view.json", {1417154, 1417154}},
      {"spd-gears/view.json", {36610, 36610}},
      {"spd-mount-s10/view.json", {2097920, 2097920}},
      {"spd-mount/view.json", {8960, 8960}},
      {"spd-rings/view.json", {940802, 940802}},
      {"spd-teapot/view.json", {2328, 2328}},
      {"spd-tetra-s8/view.json", {65536, 65536}},
      {"spd-tetra/view.json", {4096, 4096}},
      {"spd-tree/view.json", {917282, 917282}},
  };
  return views;
}

TEST(ScenePack, EveryViewLoadsWithItsTriangleCount) {
  RTC_REQUIRE_SCENE_PACK();
  int seen = 0;
  for (const auto& folder : std::filesystem::directory_iterator(scene_pack())) {
    if (!folder.is_directory()) continue;
    for (const auto& file : std::filesystem::directory_iterator(folder.path())) {
      const std::string name = file.path().filename().string();
      if (!name.starts_with("view") || file.path().extension() != ".json") continue;
      const std::string key = folder.path().filename().string() + "/" + name;
      SCOPED_TRACE(key);
      const auto it = expected_views().find(key);
      ASSERT_NE(it, expected_views().end()) << "a view this test does not know: add its counts";
      const Scene scene = load_scene(file.path());
      std::uint64_t dropped = 0;
      for (const Mesh& mesh : scene.meshes) {
        dropped += mesh.dropped_degenerate;
        ASSERT_EQ(mesh.source_index.size(), mesh.triangles.size());
        for (std::size_t i = 1; i < mesh.source_index.size(); ++i) {
          ASSERT_LT(mesh.source_index[i - 1], mesh.source_index[i]) << "input order";
        }
      }
      EXPECT_EQ(scene.triangle_count() + dropped, it->second.input);
      EXPECT_EQ(scene.triangle_count(), it->second.kept);
      EXPECT_FALSE(scene.lights.empty());
      ++seen;
    }
  }
  EXPECT_EQ(seen, static_cast<int>(expected_views().size()));
}

TEST(ScenePack, ViewFieldsAreRead) {
  RTC_REQUIRE_SCENE_PACK();
  const Scene cabin = load_scene(scene_pack() / "radiance-cabin/view.json");
  EXPECT_EQ(cabin.name, "radiance-cabin");
  EXPECT_EQ(cabin.width, 640);
  EXPECT_EQ(cabin.height, 459);
  EXPECT_EQ(cabin.camera.up, glm::vec3(0, 0, 1));
  EXPECT_EQ(cabin.lights.size(), 3u);
  EXPECT_EQ(cabin.lights[2].color, glm::vec3(0.5f, 0.5f, 0.45f));
  const Aabb box = cabin.bounds();
  EXPECT_EQ(box.lo, glm::vec3(-1.0f, -1.5f, -3.3f));
  EXPECT_NEAR(box.hi.z, 20.1666f, 1e-4f);
  // Mirrors are illum 3 in the MTL.
  int mirrors = 0;
  for (const Material& m : cabin.materials) mirrors += m.reflective ? 1 : 0;
  EXPECT_GE(mirrors, 2);
}

TEST(ScenePack, EngineDropsItsDegenerateTriangles) {
  RTC_REQUIRE_SCENE_PACK();
  const MeshFile engine = load_mesh_file(scene_pack() / "gltf-samples/2CylinderEngine.glb");
  EXPECT_EQ(engine.mesh.triangles.size() + engine.mesh.dropped_degenerate, 121496u);
  EXPECT_EQ(engine.mesh.triangles.size(), 110336u);
  EXPECT_EQ(engine.mesh.dropped_degenerate, 11160u);
  EXPECT_LT(engine.mesh.source_index.back(), 121496u);
}

double area(const Mesh& mesh) {
  double sum = 0.0;
  for (const glm::uvec3& t : mesh.triangles) {
    const glm::dvec3 a(mesh.positions[t.x]), b(mesh.positions[t.y]), c(mesh.positions[t.z]);
    sum += 0.5 * glm::length(glm::cross(b - a, c - a));
  }
  return sum;
}

TEST(ScenePack, NffTessellationMatchesThePackMeshes) {
  RTC_REQUIRE_SCENE_PACK();
  for (const char* name : {"spd-balls-s3", "spd-gears", "spd-mount", "spd-teapot", "spd-tetra",
                           "spd-balls", "spd-rings", "spd-tree"}) {
    SCOPED_TRACE(name);
    const std::filesystem::path folder = scene_pack() / name;
    std::filesystem::path mesh_path = folder / (std::string(name) + ".obj");
    if (!std::filesystem::exists(mesh_path)) mesh_path = folder / (std::string(name) + ".ply");
    const MeshFile nff = load_nff(folder / (std::string(name) + ".nff"));
    const MeshFile pack = load_mesh_file(mesh_path);
    EXPECT_EQ(nff.mesh.triangles.size() + nff.mesh.dropped_degenerate, pack.mesh.triangles.size());
    EXPECT_EQ(nff.mesh.triangles.size(), pack.mesh.triangles.size());
    const double a = area(nff.mesh), b = area(pack.mesh);
    EXPECT_NEAR(a, b, 1e-5 * b) << "same surfaces";
    // Materials follow the NFF f lines primitive by primitive, like the pack's usemtl runs.
    if (mesh_path.extension() == ".obj") {
      for (std::size_t i = 0; i < nff.mesh.triangles.size(); i += 97) {
        const glm::vec3 d = nff.materials[nff.mesh.material_ids[i]].diffuse -
                            pack.materials[pack.mesh.material_ids[i]].diffuse;
        EXPECT_LT(glm::length(d), 1e-5f) << "triangle " << i;
        EXPECT_EQ(nff.materials[nff.mesh.material_ids[i]].reflective,
                  pack.materials[pack.mesh.material_ids[i]].reflective);
      }
    }
  }
}

TEST(ScenePack, NffViewMatchesTheViewJson) {
  RTC_REQUIRE_SCENE_PACK();
  for (const char* name :
       {"spd-balls-s3", "spd-gears", "spd-mount", "spd-teapot", "spd-tetra", "spd-tree"}) {
    SCOPED_TRACE(name);
    const Scene view = load_scene(scene_pack() / name / "view.json");
    const Scene nff = load_scene(scene_pack() / name / (std::string(name) + ".nff"));
    EXPECT_EQ(nff.camera, view.camera);
    EXPECT_EQ(nff.width, view.width);
    EXPECT_EQ(nff.height, view.height);
    ASSERT_EQ(nff.lights.size(), view.lights.size());
    for (std::size_t i = 0; i < nff.lights.size(); ++i) {
      EXPECT_EQ(nff.lights[i].position, view.lights[i].position);
      // The view rounds sqrt(n)/(2n) to 6 digits.
      EXPECT_NEAR(nff.lights[i].color.x, view.lights[i].color.x, 1e-6f);
    }
    EXPECT_EQ(nff.background, glm::vec3(0.078f, 0.361f, 0.753f));
  }
}

TEST(ScenePack, CompressedNffIsRejectedWithAHint) {
  RTC_REQUIRE_SCENE_PACK();
  const std::string message =
      error_of([] { (void)load_scene(scene_pack() / "spd-tetra-s8/spd-tetra-s8.nff.gz"); });
  EXPECT_NE(message.find("decompress"), std::string::npos) << message;
}

}  // namespace
}  // namespace rtc
