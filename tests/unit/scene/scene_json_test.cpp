// The scene JSON format: every field of docs/scene-format.md, and the errors that name the
// file and the field.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include "common/scene/load.h"
#include "test_files.h"

namespace rtc {
namespace {

using ::testing::HasSubstr;
using test::error_of;
using test::TempDir;

constexpr const char* kTriangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
constexpr const char* kQuad =
    "mtllib q.mtl\nusemtl blue\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
constexpr const char* kQuadMtl = "newmtl blue\nKd 0 0 1\n";

/// A folder with tri.obj, q.obj + q.mtl and `json` as scene.json; returns the error message
/// of loading it ("" if it loads).
struct JsonCase {
  TempDir dir;
  std::filesystem::path write(const std::string& json) {
    (void)dir.write("tri.obj", kTriangle);
    (void)dir.write("q.obj", kQuad);
    (void)dir.write("q.mtl", kQuadMtl);
    return dir.write("scene.json", json);
  }
  std::string error(const std::string& json) {
    const auto path = write(json);
    return error_of([&] { (void)load_scene(path); });
  }
};

constexpr const char* kFullScene = R"({
  "name": "demo",
  "mesh": "tri.obj",
  "meshes": [
    {"file": "q.obj", "name": "floor", "transform": {"translate": [0, -1, 0], "rotate_deg_axis": [-90, 1, 0, 0], "scale": 10}},
    {"file": "tri.obj", "name": "mover", "material": "chrome",
     "transform": {"translate": [1, 2, 3], "quaternion": [1, 0, 0, 0], "scale": [1, 2, 1]}}
  ],
  "materials": [
    {"name": "chrome", "diffuse": [0.1, 0.1, 0.1], "specular": [0.9, 0.9, 0.9], "shininess": 200,
     "emission": [0, 0, 0], "reflective": true, "opacity": 1}
  ],
  "triangles": 4,
  "bounds": [[-5, -1, -5], [5, 5, 5]],
  "camera": {"eye": [0, 2, 8], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 50},
  "lights": [{"position": [5, 5, 5], "color": [1, 0.9, 0.8]}, {"position": [-5, 5, 5]}],
  "resolution": [320, 200],
  "background": [0.1, 0.2, 0.3],
  "ambient": [0.05, 0.05, 0.05],
  "render": {"max_depth": 3, "min_weight": 0.05, "spp": 4, "intersector": "watertight"},
  "source": "test", "license": "CC0", "notes": "all fields",
  "animation": {
    "frames": [0, 10],
    "camera": [{"frame": 0}, {"frame": 10, "eye": [0, 4, 8]}],
    "meshes": [{"mesh": "mover", "keys": [{"frame": 10, "translate": [3, 2, 3]}, {"frame": 0}]}],
    "lights": [{"light": 1, "keys": [{"frame": 0, "position": [-5, 5, 5]}, {"frame": 10, "position": [5, 5, 5]}]}]
  }
})";

TEST(SceneJson, LoadsEveryField) {
  JsonCase c;
  const Scene scene = load_scene(c.write(kFullScene));
  EXPECT_EQ(scene.name, "demo");
  ASSERT_EQ(scene.meshes.size(), 3u);
  EXPECT_EQ(scene.meshes[0].name, "tri") << "\"mesh\" comes first, named after its file";
  EXPECT_EQ(scene.meshes[1].name, "floor");
  EXPECT_EQ(scene.meshes[2].name, "mover");
  EXPECT_EQ(scene.triangle_count(), 4u);
  // floor: scale 10, -90 degrees about x (y up becomes z forward... the quad's +y edge goes to -z).
  const glm::vec4 corner = scene.meshes[1].world_from_object * glm::vec4(1, 1, 0, 1);
  EXPECT_NEAR(corner.x, 10.0f, 1e-5f);
  EXPECT_NEAR(corner.y, -1.0f, 1e-5f);
  EXPECT_NEAR(corner.z, -10.0f, 1e-5f);
  const glm::vec4 mover = scene.meshes[2].world_from_object * glm::vec4(0, 1, 0, 1);
  EXPECT_EQ(glm::vec3(mover), glm::vec3(1, 4, 3));
  // Materials: default, chrome (inline), blue (q.mtl); the override puts chrome on "mover".
  ASSERT_GE(scene.materials.size(), 3u);
  EXPECT_EQ(scene.materials[0], Material{});
  const Material& chrome = scene.materials.at(scene.meshes[2].material_ids[0]);
  EXPECT_EQ(chrome.name, "chrome");
  EXPECT_TRUE(chrome.reflective);
  EXPECT_EQ(chrome.shininess, 200.0f);
  EXPECT_EQ(scene.materials.at(scene.meshes[1].material_ids[0]).diffuse, glm::vec3(0, 0, 1));
  EXPECT_EQ(scene.meshes[0].material_ids[0], 0u);
  EXPECT_EQ(scene.camera.vfov_deg, 50.0f);
  ASSERT_EQ(scene.lights.size(), 2u);
  EXPECT_EQ(scene.lights[0].color, glm::vec3(1, 0.9f, 0.8f));
  EXPECT_EQ(scene.lights[1].color, glm::vec3(1.0f)) << "colour defaults to white";
  EXPECT_EQ(scene.width, 320);
  EXPECT_EQ(scene.height, 200);
  EXPECT_EQ(scene.background, glm::vec3(0.1f, 0.2f, 0.3f));
  EXPECT_EQ(scene.ambient, glm::vec3(0.05f));
  EXPECT_EQ(scene.settings.max_depth, 3);
  EXPECT_EQ(scene.settings.min_weight, 0.05f);
  EXPECT_EQ(scene.settings.spp, 4);
  EXPECT_EQ(scene.settings.intersector, Intersector::Watertight);
  const Animation& anim = scene.animation;
  EXPECT_EQ(anim.frame_begin, 0);
  EXPECT_EQ(anim.frame_end, 10);
  ASSERT_EQ(anim.camera.size(), 2u);
  EXPECT_EQ(anim.camera[0].camera, scene.camera) << "missing key fields take the scene camera";
  EXPECT_EQ(anim.camera[1].camera.eye, glm::vec3(0, 4, 8));
  ASSERT_EQ(anim.meshes.size(), 1u);
  EXPECT_EQ(anim.meshes[0].mesh, 2u);
  ASSERT_EQ(anim.meshes[0].keys.size(), 2u);
  EXPECT_EQ(anim.meshes[0].keys[0].frame, 0) << "keys are sorted by frame";
  EXPECT_EQ(anim.meshes[0].keys[0].transform.translate, glm::vec3(1, 2, 3))
      << "defaults to the static transform";
  EXPECT_EQ(anim.meshes[0].keys[1].transform.scale, glm::vec3(1, 2, 1));
  ASSERT_EQ(anim.lights.size(), 1u);
  EXPECT_EQ(anim.lights[0].light, 1u);

  const FramePose middle = pose_at(scene, 5);
  EXPECT_EQ(middle.camera.eye, glm::vec3(0, 3, 8));
  EXPECT_EQ(glm::vec3(middle.world_from_object[2] * glm::vec4(0, 0, 0, 1)), glm::vec3(2, 2, 3));
  EXPECT_EQ(middle.lights[1].position, glm::vec3(0, 5, 5));
}

TEST(SceneJson, UnknownFieldsAreRejectedWithTheirFullPath) {
  JsonCase c;
  const std::string base =
      R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "meshes": [{"mesh": 0, "keyz": []}]}})";
  EXPECT_NE(c.error(base).find("scene.json: unknown field \"animation.meshes[0].keyz\""),
            std::string::npos)
      << c.error(base);
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "colour": 1})"),
              HasSubstr("unknown field \"colour\""));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "camera": {"eye": [0,0,1], "look_at": [0,0,0], "fov": 3}})"),
              HasSubstr("unknown field \"camera.fov\""));
  EXPECT_THAT(c.error(R"({"meshes": [{"file": "tri.obj", "transform": {"rotate": [1, 0, 0, 0]}}]})"),
              HasSubstr("unknown field \"meshes[0].transform.rotate\""));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "lights": [{"position": [0,0,0], "intensity": 2}]})"),
              HasSubstr("unknown field \"lights[0].intensity\""));
}

TEST(SceneJson, WrongTypesAndLengthsNameTheField) {
  JsonCase c;
  const std::string eye =
      c.error(R"({"mesh": "tri.obj", "camera": {"eye": "far", "look_at": [0,0,0]}})");
  EXPECT_NE(
      eye.find("scene.json: field \"camera.eye\": expected an array of 3 numbers, got a string"),
      std::string::npos)
      << eye;
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "camera": {"eye": [0, 1], "look_at": [0,0,0]}})"),
              HasSubstr("\"camera.eye\": expected an array of 3 numbers, got 2 elements"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "background": [0, "x", 0]})"),
              HasSubstr("\"background[1]\": expected a number"));
  EXPECT_THAT(c.error(R"({"mesh": 7})"),
              HasSubstr("\"mesh\": expected a string, got an integer"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "resolution": [512]})"),
              HasSubstr("\"resolution\": expected 2 elements"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "resolution": [512, 1.5]})"),
              HasSubstr("\"resolution[1]\": expected an integer"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "render": {"spp": 0}})"),
              HasSubstr("\"render.spp\": must be in [1, 4096]"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "render": {"intersector": "moller"}})"),
              HasSubstr("\"render.intersector\": must be \"wald\" or \"watertight\", got \"moller\""));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "render": {"intersector": 1}})"),
              HasSubstr("\"render.intersector\": expected a string"));
  EXPECT_THAT(c.error(R"([1, 2])"),
              HasSubstr("expected an object"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "materials": [{"name": "a", "reflective": 1}]})"),
              HasSubstr("\"materials[0].reflective\": expected true or false"));
}

TEST(SceneJson, NegativeResolutionAndNonFiniteNumbersAreRejected) {
  JsonCase c;
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "resolution": [-512, 512]})"),
              HasSubstr("\"resolution[0]\": must be in [1, 65536], got -512"));
  const std::string huge = c.error(R"({"mesh": "tri.obj", "ambient": [1e999, 0, 0]})");
  EXPECT_NE(huge.find("scene.json"), std::string::npos) << huge;
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "ambient": [1e300, 0, 0]})"),
              HasSubstr("\"ambient[0]\": number out of float range"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "ambient": [NaN, 0, 0]})"),
              HasSubstr("scene.json: JSON parse error at line 1"));
}

TEST(SceneJson, SyntaxErrorNamesLineAndColumn) {
  JsonCase c;
  const std::string message = c.error("{\n  \"mesh\": \"tri.obj\",\n  \"name\" \"x\"\n}");
  EXPECT_NE(message.find("scene.json: JSON parse error at line 3, column"), std::string::npos)
      << message;
}

TEST(SceneJson, MissingMeshFileNamesFieldAndPath) {
  JsonCase c;
  const std::string message =
      c.error(R"({"meshes": [{"file": "tri.obj"}, {"file": "absent.ply"}]})");
  EXPECT_NE(
      message.find("scene.json: field \"meshes[1].file\": mesh file \"absent.ply\" not found"),
      std::string::npos)
      << message;
  EXPECT_THAT(c.error(R"({"name": "nothing"})"),
              HasSubstr("no geometry"));
  EXPECT_THAT(c.error(R"({"meshes": [{"name": "x"}]})"),
              HasSubstr("missing field \"meshes[0].file\""));
}

TEST(SceneJson, AMeshFileInALinkLoopSaysSo) {
  JsonCase c;
  std::filesystem::create_symlink("b.ply", c.dir.path() / "a.ply");
  std::filesystem::create_symlink("a.ply", c.dir.path() / "b.ply");
  EXPECT_THAT(c.error(R"({"mesh": "a.ply"})"),
              HasSubstr("field \"mesh\": mesh file \"a.ply\" cannot be used: Too many levels of symbolic links"));
}

TEST(SceneJson, BadMeshFileErrorsNameBothFiles) {
  JsonCase c;
  (void)c.dir.write("broken.obj", "v 0 0 0\nf 1 2 3\n");
  const std::string message = c.error(R"({"mesh": "broken.obj"})");
  EXPECT_NE(message.find("broken.obj:2:"), std::string::npos) << message;
  EXPECT_NE(message.find("field \"mesh\" of"), std::string::npos) << message;
}

TEST(SceneJson, RelativePathsResolveAgainstTheJsonFolder) {
  TempDir dir;
  (void)dir.write("meshes/tri.obj", kTriangle);
  const auto json = dir.write("scenes/a/scene.json", R"({"mesh": "../../meshes/tri.obj"})");
  const auto cwd = std::filesystem::current_path();
  std::filesystem::current_path(dir.path() / "meshes");  // must not matter
  const Scene scene = load_scene(json);
  std::filesystem::current_path(cwd);
  EXPECT_EQ(scene.triangle_count(), 1u);
}

// The scene's name (logs, output names): its "name" field, else the file's stem, except that a
// scene pack's view.json takes its folder's name.
TEST(SceneJson, NameDefaultsToTheFileOrAViewJsonsFolder) {
  TempDir dir;
  (void)dir.write("tri.obj", kTriangle);
  EXPECT_EQ(load_scene(dir.write("courtyard.json", R"({"mesh": "tri.obj"})")).name, "courtyard");
  EXPECT_EQ(load_scene(dir.write("named.json", R"({"mesh": "tri.obj", "name": "demo"})")).name, "demo");
  (void)dir.write("pack/spd-lab/tri.obj", kTriangle);
  EXPECT_EQ(load_scene(dir.write("pack/spd-lab/view.json", R"({"mesh": "tri.obj"})")).name, "spd-lab");
  EXPECT_EQ(load_scene(dir.write("pack/spd-lab/view.json", R"({"mesh": "tri.obj", "name": "lab"})")).name, "lab");
  // A relative path to view.json in the current folder still finds the folder's name.
  (void)dir.write("pack/spd-lab/view.json", R"({"mesh": "tri.obj"})");
  struct RestoreCwd {
    std::filesystem::path cwd = std::filesystem::current_path();
    ~RestoreCwd() { std::filesystem::current_path(cwd); }
  } restore;
  std::filesystem::current_path(dir.path() / "pack" / "spd-lab");
  EXPECT_EQ(load_scene("view.json").name, "spd-lab");
}

// A scene pack's folder stands for its view.json (as rtc-bench always took it); a folder
// without one is refused, naming the folder.
TEST(SceneJson, AFolderStandsForItsViewJson) {
  TempDir dir;
  (void)dir.write("pack/spd-lab/tri.obj", kTriangle);
  (void)dir.write("pack/spd-lab/view.json", R"({"mesh": "tri.obj", "resolution": [33, 17]})");
  const Scene scene = load_scene(dir.path() / "pack" / "spd-lab");
  EXPECT_EQ(scene.name, "spd-lab");
  EXPECT_EQ(scene.triangle_count(), 1u);
  EXPECT_EQ(scene.width, 33);
  EXPECT_EQ(scene.height, 17);
  const std::filesystem::path empty = dir.path() / "pack";
  try {
    (void)load_scene(empty);
    ADD_FAILURE() << "a folder without view.json loaded";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(empty.string() + ": is a folder without a view.json"), std::string::npos) << what;
  }
}

TEST(SceneJson, TriangleCountMismatchIsOnlyAWarning) {
  JsonCase c;
  EXPECT_EQ(load_scene(c.write(R"({"mesh": "tri.obj", "triangles": 12345})")).triangle_count(), 1u);
}

TEST(SceneJson, DefaultsWithoutCameraAndLights) {
  JsonCase c;
  const Scene scene = load_scene(c.write(R"({"mesh": "q.obj"})"));
  EXPECT_EQ(scene.width, 512);
  EXPECT_EQ(scene.height, 512);
  EXPECT_EQ(scene.lights.size(), 1u) << "a default light when the file gives none";
  EXPECT_NE(scene.camera.eye, scene.camera.look_at);
  const Scene dark = load_scene(c.write(R"({"mesh": "q.obj", "lights": []})"));
  EXPECT_TRUE(dark.lights.empty()) << "an explicit empty list stays empty";
}

TEST(SceneJson, AnimationReferencesAreChecked) {
  JsonCase c;
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "meshes": [{"mesh": "nope", "keys": [{"frame": 0}]}]}})"),
              HasSubstr("\"animation.meshes[0].mesh\": no mesh named \"nope\""));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "meshes": [{"mesh": 3, "keys": [{"frame": 0}]}]}})"),
              HasSubstr("\"animation.meshes[0].mesh\": must be in [0, 0]"));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "meshes": [{"mesh": 0, "keys": [{"frame": 1}, {"frame": 1}]}]}})"),
              HasSubstr("two keys for frame 1"));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "meshes": [{"mesh": 0, "keys": []}]}})"),
              HasSubstr("at least one key"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "animation": {"frames": [5, 1]}})"),
              HasSubstr("end frame before begin"));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "lights": [], "animation": {"frames": [0, 1], "lights": [{"light": 0, "keys": []}]}})"),
              HasSubstr("the scene has no lights"));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "camera": [{"eye": [0, 0, 1]}]}})"),
              HasSubstr("missing field \"animation.camera[0].frame\""));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "meshes": [{"file": "tri.obj", "transform": {"rotate_deg_axis": [90, 0, 0, 0]}}]})"),
              HasSubstr("rotation axis must not be zero"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "meshes": [{"file": "tri.obj", "material": "gold"}]})"),
              HasSubstr("\"meshes[0].material\": no material named \"gold\""));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "camera": {"eye": [0, 0, 0], "look_at": [0, 0, 0]}})"),
              HasSubstr("eye and look_at coincide"));
}

TEST(SceneJson, NegativeFramesAreRejected) {
  JsonCase c;
  const std::string begin =
      c.error(R"({"mesh": "tri.obj", "animation": {"frames": [-1, 5]}})");
  EXPECT_NE(begin.find("scene.json: field \"animation.frames[0]\": frame -1 is negative"),
            std::string::npos)
      << begin;
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "animation": {"frames": [-9, -2]}})"),
              HasSubstr("\"animation.frames[0]\": frame -9 is negative"));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 5], "camera": [{"frame": -3}]}})"),
              HasSubstr("\"animation.camera[0].frame\": frame -3 is negative"));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 5], "meshes": [{"mesh": 0, "keys": [{"frame": 0}, {"frame": -1}]}]}})"),
              HasSubstr("\"animation.meshes[0].keys[1].frame\": frame -1 is negative"));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 5], "lights": [{"light": 0, "keys": [{"frame": -7, "position": [0, 0, 0]}]}]}})"),
              HasSubstr("\"animation.lights[0].keys[0].frame\": frame -7 is negative"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "animation": {"frames": [0, 1000000001]}})"),
              HasSubstr("\"animation.frames[1]\": frame 1000000001 is past the last a scene may have, 1000000000"));
  // A number too large for an integer says so with its value (it said "got number").
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "resolution": [1e30, 10]})"),
              HasSubstr("\"resolution[0]\": expected an integer in [1, 65536], got 1e+30"));
}

TEST(SceneJson, TransformsBeyondTheFloatRangeAreRejected) {
  JsonCase c;
  // tri.obj reaches 1 along x and y: translate 2e38 plus scale 2e38 can reach 6e38 once
  // rotated (the check holds for every rotation, so for every pose between keys too).
  const std::string placed = c.error(
      R"({"meshes": [{"file": "tri.obj", "transform": {"translate": [2e38, 0, 0], "scale": 2e38}}]})");
  EXPECT_NE(placed.find("scene.json: field \"meshes[0].transform\": translate and scale let mesh "
                        "\"tri\" reach world coordinates of 6e+38 (for some rotation), beyond "
                        "the float range"),
            std::string::npos)
      << placed;
  EXPECT_THAT(c.error(
           R"({"meshes": [{"file": "tri.obj", "transform": {"translate": [0, 2e38, 0], "scale": [1, 2e38, 1], "rotate_deg_axis": [45, 0, 0, 1]}}]})"),
              HasSubstr("\"meshes[0].transform\": translate and scale"));
  const std::string key = c.error(
      R"({"mesh": "tri.obj", "animation": {"frames": [0, 5], "meshes": [{"mesh": 0, "keys": [{"frame": 0}, {"frame": 5, "translate": [3e38, 0, 0], "scale": 1e38}]}]}})");
  EXPECT_NE(key.find("\"animation.meshes[0].keys[1]\": translate and scale let mesh \"tri\""),
            std::string::npos)
      << key;
  EXPECT_THAT(c.error(R"({"meshes": [{"file": "tri.obj", "transform": {"scale": [1, 1, 3.3e38]}}]})"),
              HasSubstr("\"meshes[0].transform.scale\": scale must be within 3e+38"));
  // Within the range: fine, also rotated.
  EXPECT_NO_THROW((void)load_scene(c.write(
      R"({"meshes": [{"file": "tri.obj", "transform": {"translate": [5e37, 0, 0], "scale": 1e38, "rotate_deg_axis": [45, 0, 0, 1]}}], "camera": {"eye": [0, 0, 1], "look_at": [0, 0, 0]}})")));
  // An NFF view and lights move with the mesh: they must stay in range too.
  (void)c.dir.write("v.nff", "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 30\nl 9 0 0\ns 0 0 0 1\n");
  const std::string camera = c.error(
      R"({"meshes": [{"file": "v.nff", "transform": {"scale": 1e38}}]})");
  EXPECT_NE(camera.find("\"meshes[0].transform\": moves the NFF camera of \"v.nff\" beyond the "
                        "float range"),
            std::string::npos)
      << camera;
  EXPECT_THAT(c.error(R"({"meshes": [{"file": "v.nff", "transform": {"scale": 5e37}}],
                        "camera": {"eye": [0, 0, 1], "look_at": [0, 0, 0]}})"),
              HasSubstr("moves the NFF lights of \"v.nff\""));
}

TEST(SceneJson, NegativeMaterialColoursAreRejected) {
  JsonCase c;
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "materials": [{"name": "a", "diffuse": [0.5, -0.1, 0]}]})"),
              HasSubstr("\"materials[0].diffuse\": colour components must not be negative, got "
                      "[0.5, -0.1, 0]"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "materials": [{"name": "a", "specular": [-1, 0, 0]}]})"),
              HasSubstr("\"materials[0].specular\": colour components must not be negative"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "materials": [{"name": "a", "emission": [0, 0, -2]}]})"),
              HasSubstr("\"materials[0].emission\": colour components must not be negative"));
}

TEST(SceneJson, NegativeBackgroundAmbientAndLightColoursAreRejected) {
  JsonCase c;
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "background": [0, -0.5, 0]})"),
              HasSubstr("\"background\": colour components must not be negative, got [0, -0.5, 0]"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "ambient": [-1, 0, 0]})"),
              HasSubstr("\"ambient\": colour components must not be negative"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "lights": [{"position": [1, 1, 1], "color": [1, 1, -1]}]})"),
              HasSubstr("\"lights[0].color\": colour components must not be negative"));
}

TEST(SceneJson, CamerasAreJudgedByDirectionsInDouble) {
  JsonCase c;
  // A short up is a direction like any other.
  EXPECT_NO_THROW((void)load_scene(c.write(R"({"mesh": "tri.obj", "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1e-13, 0]}})")));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 0, 0]}})"),
              HasSubstr("\"camera\": up is zero"));
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 0, 2]}})"),
              HasSubstr("\"camera\": up is parallel to the view direction"));
  // look_at - eye beyond the float range is a plain view direction.
  EXPECT_NO_THROW((void)load_scene(c.write(R"({"mesh": "tri.obj", "lights": [], "camera": {"eye": [2e38, 0, 0], "look_at": [-2e38, 0, 0]}})")));
}

TEST(SceneJson, TheDefaultLightOfAFarCameraIsWhereItShouldBe) {
  // 2e19 from its target: the squared distance overflows a float.
  JsonCase c;
  const Scene scene = load_scene(c.write(R"({"mesh": "tri.obj", "camera": {"eye": [0, 0, 2e19], "look_at": [0, 0, 0]}})"));
  ASSERT_EQ(scene.lights.size(), 1u);
  // Above the eye by half the distance, beside it by a quarter: (+-5e18, 1e19, 2e19).
  const glm::vec3 p = scene.lights[0].position;
  EXPECT_FLOAT_EQ(std::fabs(p.x), 5e18f);
  EXPECT_FLOAT_EQ(p.y, 1e19f);
  EXPECT_FLOAT_EQ(p.z, 2e19f);
  EXPECT_THAT(c.error(R"({"mesh": "tri.obj", "camera": {"eye": [0, 3e38, 3e38], "look_at": [0, -3e38, -3e38]}})"),
              HasSubstr("the automatic light would lie outside the float range"));
}

TEST(SceneJson, TessellationIsChosenPerMeshEntry) {
  JsonCase c;
  (void)c.dir.write("s.nff", "s 0 0 0 1\nc 0 0 0 1 0 0 1 1\n");
  const Scene scene = load_scene(c.write(R"({"meshes": [
    {"file": "s.nff"},
    {"file": "s.nff", "tessellation": {"sphere": 8}},
    {"file": "s.nff", "tessellation": {"sphere": 2, "cone": 8}},
    {"file": "./s.nff", "tessellation": {"sphere": 4, "cone": 16}}],
    "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0]}})"));
  ASSERT_EQ(scene.meshes.size(), 4u);
  EXPECT_EQ(scene.meshes[0].triangles.size(), 192u + 32u);
  EXPECT_EQ(scene.meshes[1].triangles.size(), 768u + 32u);
  EXPECT_EQ(scene.meshes[2].triangles.size(), 48u + 16u);
  EXPECT_EQ(scene.meshes[3].positions, scene.meshes[0].positions) << "the defaults, spelled out";
  EXPECT_THAT(c.error(R"({"meshes": [{"file": "s.nff", "tessellation": {"sphere": 0}}]})"),
              HasSubstr("\"meshes[0].tessellation.sphere\": must be in [1, 1024], got 0"));
  EXPECT_THAT(c.error(R"({"meshes": [{"file": "s.nff", "tessellation": {"cone": 65537}}]})"),
              HasSubstr("\"meshes[0].tessellation.cone\": must be in [3, 65536], got 65537"));
  EXPECT_THAT(c.error(R"({"meshes": [{"file": "s.nff", "tessellation": {"spheres": 3}}]})"),
              HasSubstr("unknown field \"meshes[0].tessellation.spheres\""));
  EXPECT_THAT(c.error(R"({"meshes": [{"file": "s.nff", "tessellation": 4}]})"),
              HasSubstr("\"meshes[0].tessellation\": expected an object"));
  EXPECT_THAT(c.error(R"({"meshes": [{"file": "tri.obj", "tessellation": {"sphere": 2}}]})"),
              HasSubstr("\"meshes[0].tessellation\": only .nff meshes are tessellated"));
}

TEST(SceneJson, MeshAndLightTracksAreReadAlike) {
  JsonCase c;
  const std::string mesh_twice = c.error(
      R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "meshes": [{"mesh": 0, "keys": [{"frame": 0}]}, {"mesh": "tri", "keys": [{"frame": 1}]}]}})");
  EXPECT_NE(mesh_twice.find("\"animation.meshes[1].mesh\": mesh already has a track"),
            std::string::npos)
      << mesh_twice;
  const std::string light_twice = c.error(
      R"({"mesh": "tri.obj", "lights": [{"position": [0, 0, 0]}], "animation": {"frames": [0, 1], "lights": [{"light": 0, "keys": [{"frame": 0, "position": [1, 1, 1]}]}, {"light": 0, "keys": [{"frame": 1, "position": [1, 1, 1]}]}]}})");
  EXPECT_NE(light_twice.find("\"animation.lights[1].light\": light already has a track"),
            std::string::npos)
      << light_twice;
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "lights": [{"light": 0, "keys": [{"frame": 1, "position": [0, 0, 0]}, {"frame": 1, "position": [0, 0, 0]}]}]}})"),
              HasSubstr("\"animation.lights[0].keys\": two keys for frame 1"));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "lights": [{"light": 0, "keys": []}]}})"),
              HasSubstr("\"animation.lights[0].keys\": a track needs at least one key"));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "lights": [{"light": 0, "keys": [{"frame": 0, "translate": [0, 0, 0]}]}]}})"),
              HasSubstr("unknown field \"animation.lights[0].keys[0].translate\""));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "lights": [{"light": 0, "keys": [{"frame": 0}]}]}})"),
              HasSubstr("missing field \"animation.lights[0].keys[0].position\""));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "lights": [{"light": 3, "keys": [{"frame": 0, "position": [0, 0, 0]}]}]}})"),
              HasSubstr("\"animation.lights[0].light\": must be in [0, 0], got 3"));
  EXPECT_THAT(c.error(
           R"({"mesh": "tri.obj", "animation": {"frames": [0, 1], "meshes": [{"keys": [{"frame": 0}]}]}})"),
              HasSubstr("missing field \"animation.meshes[0].mesh\""));
  // Keys in any order come back sorted, for both kinds.
  const Scene scene = load_scene(c.write(
      R"({"mesh": "tri.obj", "lights": [{"position": [0, 0, 0]}], "animation": {"frames": [0, 9],
        "meshes": [{"mesh": 0, "keys": [{"frame": 9}, {"frame": 2}, {"frame": 5}]}],
        "lights": [{"light": 0, "keys": [{"frame": 7, "position": [7, 0, 0]}, {"frame": 1, "position": [1, 0, 0]}]}]}})"));
  ASSERT_EQ(scene.animation.meshes.size(), 1u);
  EXPECT_EQ(scene.animation.meshes[0].keys[0].frame, 2);
  EXPECT_EQ(scene.animation.meshes[0].keys[2].frame, 9);
  ASSERT_EQ(scene.animation.lights.size(), 1u);
  EXPECT_EQ(scene.animation.lights[0].keys[0].position, glm::vec3(1, 0, 0));
  EXPECT_EQ(scene.animation.lights[0].keys[1].frame, 7);
}

TEST(SceneJson, NffMeshBringsItsViewUnlessTheJsonGivesOne) {
  TempDir dir;
  (void)dir.write("s.nff",
                  "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 30\nhither 1\nresolution 100 50\nb 0.5 "
                  "0.5 0.5\nl 1 2 3\ns 0 0 0 1\n");
  const Scene scene = load_scene(dir.write("a.json", R"({"mesh": "s.nff"})"));
  EXPECT_EQ(scene.camera.vfov_deg, 30.0f);
  EXPECT_EQ(scene.width, 100);
  EXPECT_EQ(scene.background, glm::vec3(0.5f));
  ASSERT_EQ(scene.lights.size(), 1u);
  EXPECT_EQ(scene.lights[0].color, glm::vec3(0.5f));
  const Scene own = load_scene(dir.write(
      "b.json",
      R"({"mesh": "s.nff", "resolution": [64, 64], "lights": [{"position": [9, 9, 9]}]})"));
  EXPECT_EQ(own.width, 64);
  EXPECT_EQ(own.lights[0].position, glm::vec3(9.0f));
}

TEST(SceneJson, SharedMeshFilesAreLoadedOnceAndCopied) {
  JsonCase c;
  const Scene scene = load_scene(c.write(
      R"({"meshes": [{"file": "q.obj"}, {"file": "./q.obj", "transform": {"translate": [5, 0, 0]}}]})"));
  ASSERT_EQ(scene.meshes.size(), 2u);
  EXPECT_EQ(scene.meshes[0].positions, scene.meshes[1].positions);
  EXPECT_EQ(scene.meshes[0].material_ids, scene.meshes[1].material_ids);
  EXPECT_EQ(scene.triangle_count(), 4u);
}

TEST(SceneJson, DocumentedExampleLoads) {
  const std::filesystem::path doc =
      std::filesystem::path(RTC_TEST_DATA) / "../../../docs/scene-format.md";
  if (!std::filesystem::exists(doc)) GTEST_SKIP() << doc << " not found";
  std::ifstream in(doc);
  std::stringstream text;
  text << in.rdbuf();
  const std::string markdown = text.str();
  const std::size_t begin = markdown.rfind("```json\n");
  ASSERT_NE(begin, std::string::npos);
  const std::size_t end = markdown.find("```", begin + 8);
  std::string json = markdown.substr(begin + 8, end - begin - 8);
  json.replace(json.find("engine.glb"), 10, "engine.gltf");
  TempDir dir;
  const auto path = dir.write("docs/scene.json", json);
  (void)dir.write("docs/ground.obj", kQuad);
  (void)dir.write("docs/q.mtl", kQuadMtl);
  (void)dir.write("docs/sphere.nff", "s 0 0 0 1\n");
  (void)dir.write("docs/engine.gltf", test::small_gltf());
  (void)dir.write("shared/scenes/bunny/bunny.obj", kTriangle);
  const Scene scene = load_scene(path);
  EXPECT_EQ(scene.name, "courtyard");
  ASSERT_EQ(scene.meshes.size(), 4u);
  EXPECT_EQ(scene.materials.at(scene.meshes[2].material_ids[0]).name, "chrome");
  EXPECT_EQ(scene.meshes[2].triangles.size(), 768u) << "the ball's tessellation";
  EXPECT_EQ(scene.animation.frame_end, 47);
  EXPECT_EQ(scene.animation.camera.size(), 2u);
  EXPECT_EQ(scene.animation.meshes.size(), 2u);
  EXPECT_EQ(scene.animation.lights.size(), 1u);
  EXPECT_EQ(pose_at(scene, 47).lights[0].position, glm::vec3(-5, 8, 6));
}

}  // namespace
}  // namespace rtc
