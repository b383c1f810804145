// Scene bytes (serialize_scene / deserialize_scene): exact round trips of every field, the
// same bytes every time, and hostile bytes (truncated, corrupted, out-of-range) rejected with
// an rtc::Error naming the field and byte, never a crash or a huge allocation.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "common/scene/load.h"
#include "common/scene/serialize.h"
#include "test_files.h"

namespace rtc {
namespace {

using Bytes = std::vector<std::uint8_t>;
using test::error_of;
using test::scene_pack;
using ::testing::HasSubstr;
using ::testing::StartsWith;

/// True when a and b hold the same bytes (the structs compared here are floats and ints only,
/// without padding, so this compares float bits: -0 differs from +0).
template <typename T>
bool same_bytes(const T& a, const T& b) {
  static_assert(std::is_trivially_copyable_v<T>);
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}

template <typename T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  static_assert(std::is_trivially_copyable_v<T>);
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

static_assert(sizeof(Camera) == 40 && sizeof(PointLight) == 24 && sizeof(Transform) == 40);
static_assert(sizeof(CameraKey) == 44 && sizeof(TransformKey) == 44 && sizeof(LightKey) == 16);

/// Every field of the two scenes, floats bit for bit.
void expect_same_scene(const Scene& a, const Scene& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.source, b.source);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_TRUE(same_bytes(a.background, b.background));
  EXPECT_TRUE(same_bytes(a.ambient, b.ambient));
  EXPECT_EQ(a.settings.max_depth, b.settings.max_depth);
  EXPECT_EQ(std::bit_cast<std::uint32_t>(a.settings.min_weight),
            std::bit_cast<std::uint32_t>(b.settings.min_weight));
  EXPECT_EQ(a.settings.spp, b.settings.spp);
  EXPECT_EQ(a.settings.intersector, b.settings.intersector);
  EXPECT_TRUE(same_bytes(a.camera, b.camera));
  EXPECT_EQ(a.camera_automatic, b.camera_automatic);

  ASSERT_EQ(a.materials.size(), b.materials.size());
  for (std::size_t i = 0; i < a.materials.size(); ++i) {
    SCOPED_TRACE("material " + std::to_string(i));
    const Material& x = a.materials[i];
    const Material& y = b.materials[i];
    EXPECT_EQ(x.name, y.name);
    EXPECT_TRUE(same_bytes(x.diffuse, y.diffuse));
    EXPECT_TRUE(same_bytes(x.specular, y.specular));
    EXPECT_TRUE(same_bytes(x.shininess, y.shininess));
    EXPECT_TRUE(same_bytes(x.emission, y.emission));
    EXPECT_EQ(x.reflective, y.reflective);
    EXPECT_TRUE(same_bytes(x.opacity, y.opacity));
  }
  EXPECT_TRUE(same_bytes(a.lights, b.lights));

  ASSERT_EQ(a.meshes.size(), b.meshes.size());
  for (std::size_t i = 0; i < a.meshes.size(); ++i) {
    SCOPED_TRACE("mesh " + std::to_string(i));
    const Mesh& x = a.meshes[i];
    const Mesh& y = b.meshes[i];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.source, y.source);
    EXPECT_TRUE(same_bytes(x.positions, y.positions));
    EXPECT_TRUE(same_bytes(x.normals, y.normals));
    EXPECT_TRUE(same_bytes(x.triangles, y.triangles));
    EXPECT_EQ(x.material_ids, y.material_ids);
    EXPECT_EQ(x.source_index, y.source_index);
    EXPECT_EQ(x.dropped_degenerate, y.dropped_degenerate);
    EXPECT_TRUE(same_bytes(x.world_from_object, y.world_from_object));
  }

  const Animation& p = a.animation;
  const Animation& q = b.animation;
  EXPECT_EQ(p.frame_begin, q.frame_begin);
  EXPECT_EQ(p.frame_end, q.frame_end);
  EXPECT_TRUE(same_bytes(p.camera, q.camera));
  ASSERT_EQ(p.meshes.size(), q.meshes.size());
  for (std::size_t i = 0; i < p.meshes.size(); ++i) {
    EXPECT_EQ(p.meshes[i].mesh, q.meshes[i].mesh);
    EXPECT_TRUE(same_bytes(p.meshes[i].keys, q.meshes[i].keys)) << "mesh track " << i;
  }
  ASSERT_EQ(p.lights.size(), q.lights.size());
  for (std::size_t i = 0; i < p.lights.size(); ++i) {
    EXPECT_EQ(p.lights[i].light, q.lights[i].light);
    EXPECT_TRUE(same_bytes(p.lights[i].keys, q.lights[i].keys)) << "light track " << i;
  }
}

Scene round_trip(const Scene& scene) { return deserialize_scene(serialize_scene(scene), "test"); }

/// Two meshes (one smooth), three materials, two lights and every kind of track.
Scene small_scene() {
  Scene scene = test::one_triangle_scene();
  scene.name = "small";
  scene.materials.push_back(Material{"red", glm::vec3(1, 0, 0)});
  Mesh smooth;
  smooth.name = "quad";
  smooth.source = "quad.obj";
  smooth.positions = {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  smooth.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  smooth.triangles = {{0, 1, 2}, {0, 2, 3}};
  smooth.material_ids = {1, 0};
  smooth.source_index = {0, 2};
  smooth.dropped_degenerate = 1;
  scene.meshes.push_back(smooth);
  scene.lights = {PointLight{{0, 5, 0}, glm::vec3(1.0f)}, PointLight{{3, 5, 1}, glm::vec3(0.5f)}};
  scene.animation.frame_begin = 0;
  scene.animation.frame_end = 4;
  CameraKey moved{4, scene.camera};
  moved.camera.eye = {1, 1, 3};
  scene.animation.camera = {CameraKey{0, scene.camera}, moved};
  Transform turned;
  turned.rotate = glm::quat(0.0f, 0.0f, 1.0f, 0.0f);
  scene.animation.meshes = {MeshTrack{1, {TransformKey{0, Transform{}}, TransformKey{4, turned}}}};
  scene.animation.lights = {LightTrack{1, {LightKey{2, {3, 6, 1}}}}};
  return scene;
}

/// A scene with a value in every field, including bit patterns a text format would lose.
Scene every_field_scene() {
  Scene scene = small_scene();
  scene.name = std::string("every field \xc3\xa9\0 nul", 20);
  scene.source = "/scenes/every/field.json";
  scene.width = 641;
  scene.height = 359;
  scene.background = {0.25f, -0.0f, 1e-40f};  // -0 and a denormal keep their bits
  scene.ambient = {0.1f, 0.2f, 0.30000001f};
  scene.settings = RenderSettings{7, 0.125f, 3, Intersector::Watertight};
  scene.camera = Camera{{1.5f, 2.5f, 9.0f}, {0.1f, 0.2f, -0.3f}, {0.0f, 1.0f, 0.1f}, 38.5f};
  scene.camera_automatic = true;
  scene.materials.push_back(Material{"mirror", glm::vec3(0.1f, 0.2f, 0.3f),
                                     glm::vec3(0.9f, 0.8f, 0.7f), 1e5f,
                                     glm::vec3(0.01f, 0.0f, 2.0f), true, 0.5f});
  scene.meshes[0].name = "tri";
  scene.meshes[0].source = "tri.ply";
  scene.meshes[0].material_ids = {2};
  scene.meshes[0].source_index = {4000000000u};
  scene.meshes[0].dropped_degenerate = std::uint64_t{1} << 40;
  scene.meshes[0].world_from_object = glm::scale(
      glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(1, -2, 3)), 0.3f, glm::vec3(0, 1, 0)),
      glm::vec3(2.0f, 0.5f, -1.0f));
  scene.meshes[1].normals[2] = {0.0f, 0.0f, 0.0f};  // "use the geometric normal"
  scene.animation.frame_begin = 2;
  scene.animation.frame_end = 9;
  scene.animation.camera[0].frame = 2;
  scene.animation.camera[1].frame = 9;
  Transform t;
  t.translate = {0.5f, 0.25f, -8.0f};
  t.rotate = glm::normalize(glm::quat(0.9f, 0.1f, -0.2f, 0.3f));
  t.scale = {1.0f, 3.0f, 0.75f};
  scene.animation.meshes.push_back(
      MeshTrack{0, {TransformKey{3, t}, TransformKey{5, Transform{}}}});
  scene.animation.lights.push_back(
      LightTrack{0, {LightKey{2, {1, 2, 3}}, LightKey{9, {-1, -2, -3}}}});
  return scene;
}

TEST(SceneBytes, DefaultSceneRoundTripsBitForBit) {
  const Scene scene = default_scene();
  const Bytes bytes = serialize_scene(scene);
  const Scene copy = deserialize_scene(bytes, "default");
  expect_same_scene(scene, copy);
  EXPECT_EQ(serialize_scene(copy), bytes);
}

TEST(SceneBytes, EveryFieldRoundTripsBitForBit) {
  const Scene scene = every_field_scene();
  const Scene copy = round_trip(scene);
  expect_same_scene(scene, copy);
  EXPECT_EQ(copy.name.size(), 20u);
  EXPECT_EQ(std::bit_cast<std::uint32_t>(copy.background.y), 0x80000000u);
}

TEST(SceneBytes, SameSceneGivesTheSameBytes) {
  const Scene scene = every_field_scene();
  const Bytes first = serialize_scene(scene);
  EXPECT_EQ(serialize_scene(scene), first);
  EXPECT_EQ(serialize_scene(Scene(scene)), first);
  EXPECT_EQ(serialize_scene(default_scene()), serialize_scene(default_scene()));
}

TEST(SceneBytes, ReserializingDecodedBytesGivesTheSameBytes) {
  for (const Scene& scene : {small_scene(), every_field_scene(), default_scene()}) {
    const Bytes bytes = serialize_scene(scene);
    EXPECT_EQ(serialize_scene(deserialize_scene(bytes, "test")), bytes) << scene.name;
  }
}

TEST(SceneBytes, StartsWithMagicAndVersion) {
  const Bytes bytes = serialize_scene(small_scene());
  ASSERT_GE(bytes.size(), 12u);
  EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + 4), "RTCS");
  EXPECT_EQ(bytes[4], 2);
  EXPECT_EQ(bytes[5] | bytes[6] | bytes[7], 0);
  EXPECT_EQ(std::string(bytes.begin() + 8, bytes.begin() + 12), "SCEN");
}

TEST(SceneBytes, EveryTruncationThrows) {
  const Bytes bytes = serialize_scene(small_scene());
  ASSERT_LT(bytes.size(), 4096u) << "keep the loop short";
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const std::string message =
        error_of([&] { (void)deserialize_scene(std::span(bytes.data(), n), "cut.bin"); });
    ASSERT_THAT(message, StartsWith("cut.bin: ")) << "prefix of " << n << " bytes";
    ASSERT_THAT(message, HasSubstr(" at byte ")) << "prefix of " << n << " bytes";
  }
}

/// The offset just after the first occurrence of a 4-byte section tag.
std::size_t after_tag(const Bytes& bytes, const char* tag) {
  for (std::size_t i = 0; i + 4 <= bytes.size(); ++i) {
    if (std::memcmp(bytes.data() + i, tag, 4) == 0) return i + 4;
  }
  ADD_FAILURE() << "no section " << tag;
  return 0;
}

void put_u32(Bytes& bytes, std::size_t at, std::uint32_t v) {
  std::memcpy(bytes.data() + at, &v, 4);
}

std::string error_for(const Bytes& bytes) {
  return error_of([&] { (void)deserialize_scene(bytes, "scene.bin"); });
}

std::string error_for(const Scene& scene) { return error_for(serialize_scene(scene)); }

TEST(SceneBytes, RejectsBadMagicVersionAndTrailingBytes) {
  const Bytes good = serialize_scene(small_scene());
  Bytes bytes = good;
  bytes[0] = 'X';
  EXPECT_THAT(error_for(bytes), HasSubstr("scene.bin: magic at byte 0: not scene bytes"));
  bytes = good;
  bytes[4] = 1;  // version 1 had no intersector byte
  EXPECT_THAT(error_for(bytes), HasSubstr("unsupported format version 1 (this build reads 2)"));
  bytes[4] = 3;
  EXPECT_THAT(error_for(bytes), HasSubstr("unsupported format version 3"));
  bytes = good;
  bytes.push_back(0);
  EXPECT_THAT(error_for(bytes), HasSubstr("1 trailing bytes"));
  bytes = good;
  put_u32(bytes, after_tag(bytes, "LGHT") - 4, 0x54484749);
  EXPECT_THAT(error_for(bytes), HasSubstr("expected section \"LGHT\""));
  EXPECT_THAT(error_for(Bytes{}), HasSubstr("scene.bin: magic at byte 0"));
}

TEST(SceneBytes, RejectsCountsBeyondTheRemainingBytesBeforeAllocating) {
  const Bytes good = serialize_scene(small_scene());
  struct Case {
    const char* tag;
    std::size_t offset;  // of the count after the tag
    const char* field;
  };
  // MESH: count, then mesh 0: name "" (4), source "" (4), dropped (8), matrix (64), positions.
  const Case cases[] = {{"MATL", 0, "materials count"},
                        {"LGHT", 0, "lights count"},
                        {"MESH", 0, "meshes count"},
                        {"MESH", 4 + 4 + 4 + 8 + 64, "meshes[0].positions count"},
                        {"ANIM", 8, "animation.camera count"}};
  for (const Case& c : cases) {
    for (const std::uint32_t count : {0xffffffffu, 0x10000000u, 1000u}) {
      Bytes bytes = good;
      put_u32(bytes, after_tag(bytes, c.tag) + c.offset, count);
      const std::string message = error_for(bytes);
      EXPECT_THAT(message, HasSubstr(c.field)) << count;
      EXPECT_THAT(message, HasSubstr("count " + std::to_string(count) + " needs at least"))
          << c.field;
    }
  }
}

TEST(SceneBytes, RejectsMissingMaterials) {
  Scene scene = small_scene();
  scene.materials.clear();
  scene.meshes.clear();
  scene.animation.meshes.clear();
  EXPECT_THAT(error_for(scene), HasSubstr("materials at byte"));
  EXPECT_THAT(error_for(scene), HasSubstr("no materials"));
}

TEST(SceneBytes, RejectsIndicesOutOfRange) {
  Scene scene = small_scene();
  scene.meshes[1].triangles[1] = {0, 2, 4};
  EXPECT_THAT(error_for(scene), HasSubstr("meshes[1].triangles[1] at byte"));
  EXPECT_THAT(error_for(scene), HasSubstr("(0, 2, 4) reach beyond the 4 positions"));

  scene = small_scene();
  scene.meshes[1].material_ids[1] = 2;
  EXPECT_THAT(error_for(scene), HasSubstr("meshes[1].material_ids[1]"));
  EXPECT_THAT(error_for(scene), HasSubstr("material 2 of 2 materials"));

  scene = small_scene();
  scene.animation.meshes[0].mesh = 2;
  EXPECT_THAT(error_for(scene), HasSubstr("animation.meshes[0].mesh"));
  EXPECT_THAT(error_for(scene), HasSubstr("mesh index 2 out of range (2 in the scene)"));

  scene = small_scene();
  scene.animation.lights[0].light = 7;
  EXPECT_THAT(error_for(scene), HasSubstr("light index 7 out of range (2 in the scene)"));

  scene = small_scene();
  scene.animation.lights.push_back(scene.animation.lights[0]);
  EXPECT_THAT(error_for(scene), HasSubstr("light 1 already has a track"));
}

TEST(SceneBytes, RejectsArraysOfTheWrongLength) {
  Scene scene = small_scene();
  scene.meshes[1].normals.pop_back();
  EXPECT_THAT(error_for(scene), HasSubstr("meshes[1].normals count"));
  EXPECT_THAT(error_for(scene), HasSubstr("3 normals for 4 positions"));

  scene = small_scene();
  scene.meshes[1].material_ids.push_back(0);
  EXPECT_THAT(error_for(scene), HasSubstr("meshes[1].material_ids count"));
  EXPECT_THAT(error_for(scene), HasSubstr("3 entries for 2 triangles"));

  scene = small_scene();
  scene.meshes[0].source_index.clear();
  EXPECT_THAT(error_for(scene), HasSubstr("meshes[0].source_index count"));
  EXPECT_THAT(error_for(scene), HasSubstr("0 entries for 1 triangles"));

  // An empty track before one with enough keys that the track count itself passes.
  scene = small_scene();
  scene.animation.lights = {LightTrack{0, {}},
                            LightTrack{1, {LightKey{0, {}}, LightKey{1, {}}, LightKey{2, {}}}}};
  EXPECT_THAT(error_for(scene), HasSubstr("animation.lights[0].keys count"));
  EXPECT_THAT(error_for(scene), HasSubstr("a track needs at least one key"));
}

TEST(SceneBytes, RejectsUnsortedKeysAndBadFrames) {
  Scene scene = small_scene();
  std::swap(scene.animation.camera[0], scene.animation.camera[1]);
  EXPECT_THAT(error_for(scene), HasSubstr("animation.camera[1].frame"));
  EXPECT_THAT(error_for(scene), HasSubstr("frame 0 after frame 4: keys must be sorted"));

  scene = small_scene();
  scene.animation.meshes[0].keys[1].frame = 0;  // the same frame twice
  EXPECT_THAT(error_for(scene), HasSubstr("animation.meshes[0].keys[1].frame"));
  EXPECT_THAT(error_for(scene), HasSubstr("keys must be sorted"));

  scene = small_scene();
  scene.animation.lights[0].keys[0].frame = -1;
  EXPECT_THAT(error_for(scene), HasSubstr("frame must be in [0, 1000000000], got -1"));

  scene = small_scene();
  scene.animation.frame_end = -3;
  EXPECT_THAT(error_for(scene), HasSubstr("animation.frame_end"));

  scene = small_scene();
  scene.animation.frame_begin = 5;
  EXPECT_THAT(error_for(scene), HasSubstr("end frame 4 before begin frame 5"));
}

TEST(SceneBytes, RejectsNonFiniteValues) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<std::pair<std::string, std::function<void(Scene&)>>> cases = {
      {"meshes[1].positions[3]", [&](Scene& s) { s.meshes[1].positions[3].y = nan; }},
      {"meshes[1].normals[0]", [&](Scene& s) { s.meshes[1].normals[0].z = -inf; }},
      {"meshes[0].world_from_object", [&](Scene& s) { s.meshes[0].world_from_object[3][1] = inf; }},
      {"camera.eye", [&](Scene& s) { s.camera.eye.x = nan; }},
      {"camera.vfov_deg", [&](Scene& s) { s.camera.vfov_deg = inf; }},
      {"lights[1].position", [&](Scene& s) { s.lights[1].position.x = inf; }},
      {"lights[0].color", [&](Scene& s) { s.lights[0].color.y = nan; }},
      {"materials[1].diffuse", [&](Scene& s) { s.materials[1].diffuse.x = nan; }},
      {"materials[0].shininess", [&](Scene& s) { s.materials[0].shininess = inf; }},
      {"materials[1].opacity", [&](Scene& s) { s.materials[1].opacity = nan; }},
      {"materials[0].emission", [&](Scene& s) { s.materials[0].emission.z = inf; }},
      {"background", [&](Scene& s) { s.background.x = nan; }},
      {"animation.camera[1].up", [&](Scene& s) { s.animation.camera[1].camera.up.y = nan; }},
      {"animation.meshes[0].keys[1].rotate.w",
       [&](Scene& s) { s.animation.meshes[0].keys[1].transform.rotate.w = nan; }},
      {"animation.meshes[0].keys[0].scale",
       [&](Scene& s) { s.animation.meshes[0].keys[0].transform.scale.z = inf; }},
      {"animation.lights[0].keys[0].position",
       [&](Scene& s) { s.animation.lights[0].keys[0].position.x = nan; }},
  };
  for (const auto& [field, spoil] : cases) {
    Scene scene = small_scene();
    spoil(scene);
    const std::string message = error_for(scene);
    EXPECT_THAT(message, HasSubstr(field + " at byte")) << field;
    EXPECT_THAT(message, HasSubstr("not finite")) << field;
  }
}

TEST(SceneBytes, RejectsSettingsAndSizesOutOfRange) {
  const std::vector<std::pair<std::string, std::function<void(Scene&)>>> cases = {
      {"width at byte", [](Scene& s) { s.width = 0; }},
      {"width at byte", [](Scene& s) { s.width = 32769; }},
      {"height at byte", [](Scene& s) { s.height = -5; }},
      {"must be in [1, 32768], got 40000", [](Scene& s) { s.height = 40000; }},
      {"max_depth must be in [0, 64], got 65", [](Scene& s) { s.settings.max_depth = 65; }},
      {"max_depth must be in [0, 64], got -1", [](Scene& s) { s.settings.max_depth = -1; }},
      {"spp must be in [1, 4096], got 0", [](Scene& s) { s.settings.spp = 0; }},
      {"spp must be in [1, 4096], got 4097", [](Scene& s) { s.settings.spp = 4097; }},
      {"min_weight must be in [0, 1]", [](Scene& s) { s.settings.min_weight = std::nanf(""); }},
      {"settings at byte", [](Scene& s) { s.settings.intersector = static_cast<Intersector>(2); }},
      {"intersector must be 0 (wald) or 1 (watertight), got 2",
       [](Scene& s) { s.settings.intersector = static_cast<Intersector>(2); }},
  };
  for (const auto& [expected, spoil] : cases) {
    Scene scene = small_scene();
    spoil(scene);
    EXPECT_THAT(error_for(scene), HasSubstr(expected));
  }
  Scene edge = small_scene();
  edge.width = 32768;
  edge.height = 1;
  edge.settings = RenderSettings{64, 1.0f, 4096};
  EXPECT_EQ(round_trip(edge).width, 32768);
}

TEST(SceneBytes, RejectsBooleansOtherThanZeroOrOne) {
  const Scene scene = small_scene();
  Bytes bytes = serialize_scene(scene);
  // SCEN: name, source, width, height, background, ambient, max_depth, min_weight, spp,
  // intersector, then camera_automatic.
  const std::size_t at =
      after_tag(bytes, "SCEN") + 4 + scene.name.size() + 4 + 4 + 4 + 12 + 12 + 4 + 4 + 4 + 1;
  ASSERT_EQ(bytes[at], 0);
  bytes[at] = 2;
  EXPECT_THAT(error_for(bytes), HasSubstr("camera_automatic at byte " + std::to_string(at) +
                                          ": expected 0 or 1, got 2"));
}

// Corrupted bytes either decode (and then re-encode to exactly those bytes: the format has one
// spelling per scene) or throw rtc::Error; nothing else, whatever the seed.
TEST(SceneBytes, RandomCorruptionOnlyThrowsRtcErrorOrDecodesCanonically) {
  const std::uint32_t seed = 20240611;
  SCOPED_TRACE("seed " + std::to_string(seed));
  std::mt19937 rng(seed);
  const Bytes good = serialize_scene(small_scene());
  int decoded = 0;
  for (int iteration = 0; iteration < 3000; ++iteration) {
    Bytes bytes = good;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) {
      const std::size_t at = rng() % bytes.size();
      switch (rng() % 4) {
        case 0:
          bytes[at] = static_cast<std::uint8_t>(rng());
          break;
        case 1:
          bytes[at] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
          break;
        case 2:
          bytes[at] = 0xff;
          break;
        default:
          bytes.resize(at + 1);  // cut short
          break;
      }
    }
    try {
      const Scene scene = deserialize_scene(bytes, "fuzz");
      ++decoded;
      ASSERT_EQ(serialize_scene(scene), bytes) << "iteration " << iteration;
    } catch (const Error& e) {
      ASSERT_THAT(std::string(e.what()), StartsWith("fuzz: ")) << "iteration " << iteration;
    } catch (const std::exception& e) {
      FAIL() << "iteration " << iteration << ": not an rtc::Error: " << e.what();
    }
  }
  EXPECT_GT(decoded, 0) << "some corruptions (inside floats and names) should still decode";
}

TEST(SceneBytes, SharedScenesRoundTrip) {
  RTC_REQUIRE_SCENE_PACK();
  for (const char* view :
       {"spd-teapot/view.json", "bunny/view.json", "gltf-samples/view-BoxTextured.json"}) {
    SCOPED_TRACE(view);
    const std::filesystem::path path = scene_pack() / view;
    if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not in the scene pack; skipping";
    const Scene scene = load_scene(path);
    const Bytes bytes = serialize_scene(scene);
    const Scene copy = deserialize_scene(bytes, view);
    expect_same_scene(scene, copy);
    EXPECT_EQ(serialize_scene(copy), bytes);
  }
}

}  // namespace
}  // namespace rtc
