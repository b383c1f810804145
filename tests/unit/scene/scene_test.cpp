// Scene model: transforms, animation evaluation, bounds, automatic framing and the built-in
// default scene.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <numbers>
#include <random>
#include <string>

#include "common/base/error.h"
#include "common/math/camera.h"
#include "common/scene/load.h"
#include "test_files.h"

namespace rtc {
namespace {

using test::TempDir;

Transform rotated_about_y(float degrees, glm::vec3 translate = glm::vec3(0.0f)) {
  Transform t;
  t.translate = translate;
  t.rotate = glm::angleAxis(glm::radians(degrees), glm::vec3(0, 1, 0));
  return t;
}

void expect_near(const glm::vec3& actual, const glm::vec3& expected, float tolerance = 1e-5f) {
  EXPECT_NEAR(actual.x, expected.x, tolerance);
  EXPECT_NEAR(actual.y, expected.y, tolerance);
  EXPECT_NEAR(actual.z, expected.z, tolerance);
}

/// A one-triangle scene with mesh and light tracks over frames 0..20.
Scene animated_scene() {
  Scene scene = test::one_triangle_scene();
  scene.meshes.push_back(scene.meshes[0]);
  scene.meshes[1].world_from_object = glm::translate(glm::mat4(1.0f), glm::vec3(0, 0, -7));
  scene.lights = {PointLight{{0, 10, 0}, glm::vec3(1.0f)}};
  scene.animation.frame_begin = 0;
  scene.animation.frame_end = 20;
  MeshTrack track;
  track.mesh = 0;
  track.keys = {TransformKey{10, rotated_about_y(0.0f, {2, 0, 0})},
                TransformKey{20, rotated_about_y(90.0f, {4, 0, 0})}};
  scene.animation.meshes.push_back(track);
  LightTrack light;
  light.light = 0;
  light.keys = {LightKey{0, {0, 10, 0}}, LightKey{20, {20, 10, 0}}};
  scene.animation.lights.push_back(light);
  CameraKey first, second;
  first.frame = 0;
  second.frame = 20;
  second.camera.eye = {0, 0, 3};
  second.camera.vfov_deg = 65.0f;
  scene.animation.camera = {first, second};
  return scene;
}

TEST(Transform, MatrixAppliesScaleThenRotationThenTranslation) {
  Transform t = rotated_about_y(90.0f, {1, 2, 3});
  t.scale = {2, 3, 4};
  const glm::vec3 p(t.matrix() * glm::vec4(1, 1, 1, 1));
  // scale -> (2, 3, 4); 90 degrees about y maps x to -z and z to x -> (4, 3, -2); + (1, 2, 3).
  expect_near(p, {5, 5, 1});
  EXPECT_EQ(Transform{}.matrix(), glm::mat4(1.0f));
}

TEST(PoseAt, InterpolatesLinearlyBetweenKeys) {
  const Scene scene = animated_scene();
  const FramePose pose = pose_at(scene, 15);
  EXPECT_EQ(pose.frame, 15);
  expect_near(glm::vec3(pose.world_from_object[0][3]), {3, 0, 0});
  EXPECT_EQ(pose.lights[0].position, glm::vec3(15, 10, 0));
  const FramePose camera = pose_at(scene, 5);
  EXPECT_EQ(camera.camera.eye, glm::vec3(0, 0, 1.5f));
  EXPECT_EQ(camera.camera.vfov_deg, 50.0f);
}

TEST(PoseAt, SlerpsRotations) {
  const Scene scene = animated_scene();
  const glm::mat4 m = pose_at(scene, 15).world_from_object[0];
  // Halfway between 0 and 90 degrees about y: x axis goes to (cos 45, 0, -sin 45).
  const float h = std::sqrt(0.5f);
  expect_near(glm::vec3(m[0]), {h, 0, -h});
  expect_near(glm::vec3(m[1]), {0, 1, 0});
}

glm::dquat random_unit_quaternion(std::mt19937& rng) {
  std::normal_distribution<double> gauss;
  return glm::normalize(glm::dquat(gauss(rng), gauss(rng), gauss(rng), gauss(rng)));
}

double distance(const glm::dquat& a, const glm::dquat& b) { return glm::length(a - b); }

TEST(Slerp, MatchesGlmSlerp) {
  const unsigned seed = 11;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> t(0.0, 1.0), tiny(-1e-4, 1e-4);
  for (int i = 0; i < 20000; ++i) {
    const glm::dquat a = random_unit_quaternion(rng);
    // Every other pair nearly equal: the small angles where acos(dot) is ill-conditioned.
    glm::dquat b = random_unit_quaternion(rng);
    if (i % 2 == 1) b = glm::normalize(a + glm::dquat(tiny(rng), tiny(rng), tiny(rng), tiny(rng)));
    const double u = t(rng);
    ASSERT_LT(distance(slerp_shortest(a, b, u), glm::slerp(a, b, u)), 1e-9)
        << "pair " << i << ", seed " << seed;
  }
}

TEST(Slerp, TakesTheShorterArcAndHitsTheEnds) {
  const glm::dquat a = rotation_deg_axis(10.0, {0, 1, 0});
  const glm::dquat b = rotation_deg_axis(50.0, {0, 1, 0});
  // -b is the same rotation as b: the path from a stays the 40 degree one.
  const glm::dquat mid = slerp_shortest(a, -b, 0.5);
  EXPECT_LT(distance(mid, rotation_deg_axis(30.0, {0, 1, 0})), 1e-15);
  EXPECT_LT(distance(slerp_shortest(a, b, 0.0), a), 1e-15);
  EXPECT_LT(distance(slerp_shortest(a, b, 1.0), b), 1e-15);
  // 350 degrees about y is -10 degrees: a quarter of the way from 0 goes to -2.5 degrees.
  const glm::dquat quarter =
      slerp_shortest(glm::dquat(1, 0, 0, 0), rotation_deg_axis(350.0, {0, 1, 0}), 0.25);
  EXPECT_LT(distance(quarter, rotation_deg_axis(-2.5, {0, 1, 0})), 1e-15);
}

TEST(Slerp, NearlyEqualQuaternionsFallBackToNormalisedLerp) {
  const glm::dquat a = rotation_deg_axis(20.0, glm::normalize(glm::dvec3(1, 2, 3)));
  const glm::dquat b = glm::normalize(a + glm::dquat(0, 1e-9, 0, 0));
  for (const glm::dquat& end : {a, b}) {
    const glm::dquat q = slerp_shortest(a, end, 0.3);
    EXPECT_NEAR(glm::length(q), 1.0, 1e-15);
    EXPECT_LT(distance(q, a), 1e-9);
  }
}

TEST(RotationDegAxis, MatchesGlmAngleAxis) {
  const glm::dvec3 axis = glm::normalize(glm::dvec3(1, -2, 0.5));
  for (double degrees = -1000.0; degrees <= 1000.0; degrees += 7.25) {
    const glm::dquat want = glm::angleAxis(glm::radians(degrees), axis);
    EXPECT_LT(distance(rotation_deg_axis(degrees, axis), want), 1e-13) << degrees;
  }
  // 720 degrees is the identity; 1e300 degrees is reduced exactly instead of turning into noise.
  EXPECT_EQ(rotation_deg_axis(720.0, axis), glm::dquat(1, 0, 0, 0));
  const glm::dquat huge = rotation_deg_axis(1e300, axis);
  EXPECT_NEAR(glm::length(huge), 1.0, 1e-15);
  EXPECT_EQ(huge, rotation_deg_axis(std::fmod(1e300, 720.0), axis));
}

TEST(PoseAt, SlerpMatchesGlmForRandomKeys) {
  const unsigned seed = 12;
  std::mt19937 rng(seed);
  Scene scene = animated_scene();
  for (int i = 0; i < 200; ++i) {
    const glm::dquat a = random_unit_quaternion(rng), b = random_unit_quaternion(rng);
    scene.animation.meshes[0].keys[0].transform.rotate = glm::quat(a);
    scene.animation.meshes[0].keys[1].transform.rotate = glm::quat(b);
    const Transform& ka = scene.animation.meshes[0].keys[0].transform;
    const Transform& kb = scene.animation.meshes[0].keys[1].transform;
    const int frame = 11 + i % 9;
    const double t = (frame - 10) / 10.0;
    Transform want;
    want.translate = glm::vec3(glm::mix(glm::dvec3(ka.translate), glm::dvec3(kb.translate), t));
    const glm::dquat qa(ka.rotate.w, ka.rotate.x, ka.rotate.y, ka.rotate.z);
    const glm::dquat qb(kb.rotate.w, kb.rotate.x, kb.rotate.y, kb.rotate.z);
    want.rotate = glm::quat(glm::slerp(glm::normalize(qa), glm::normalize(qb), t));
    const glm::mat4 got = pose_at(scene, frame).world_from_object[0];
    const glm::mat4 expected = want.matrix();
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 4; ++r) {
        ASSERT_NEAR(got[c][r], expected[c][r], 1e-6) << "key pair " << i << ", seed " << seed;
      }
    }
  }
}

TEST(PoseAt, HoldsTheNearestKeyOutsideTheKeyedRange) {
  const Scene scene = animated_scene();
  // Frames before the first key (10) hold it, exactly.
  EXPECT_EQ(pose_at(scene, 3).world_from_object[0], rotated_about_y(0.0f, {2, 0, 0}).matrix());
  EXPECT_EQ(pose_at(scene, -50).world_from_object[0], pose_at(scene, 10).world_from_object[0]);
  EXPECT_EQ(pose_at(scene, 99).world_from_object[0], pose_at(scene, 20).world_from_object[0]);
  EXPECT_EQ(pose_at(scene, 99).lights[0].position, glm::vec3(20, 10, 0));
  EXPECT_EQ(pose_at(scene, 99).camera.eye, glm::vec3(0, 0, 3));
}

TEST(PoseAt, MeshesWithoutTracksKeepTheirPlacement) {
  Scene scene = animated_scene();
  EXPECT_EQ(pose_at(scene, 7).world_from_object[1], scene.meshes[1].world_from_object);
  scene.animation = Animation{};
  const FramePose still = pose_at(scene, 7);
  EXPECT_EQ(still.camera, scene.camera);
  EXPECT_EQ(still.lights, scene.lights);
  EXPECT_EQ(still.world_from_object[0], glm::mat4(1.0f));
}

// A placement whose interpolation with itself rounds: scale, an oblique rotation, thirds.
Transform oblique() {
  Transform t;
  t.translate = {0.1f, 0.7f, -2.3f};
  t.rotate = glm::angleAxis(glm::radians(37.0f), glm::normalize(glm::vec3(0.3f, 1.0f, -0.2f)));
  t.scale = glm::vec3(1.3f, 0.7f, 1.1f);
  return t;
}

TEST(PoseAt, EqualKeysHoldTheirPlacementExactly) {
  // Between equal keys the mesh must not move at all (its kd-tree is built once), not even by
  // the rounding of interpolating a placement with itself.
  Scene scene = animated_scene();
  scene.animation.meshes[0].keys = {TransformKey{0, oblique()}, TransformKey{30, oblique()},
                                    TransformKey{40, rotated_about_y(10.0f)}};
  for (int frame = 0; frame <= 30; ++frame) {
    EXPECT_EQ(pose_at(scene, frame).world_from_object[0], oblique().matrix()) << "frame " << frame;
  }
  EXPECT_NE(pose_at(scene, 35).world_from_object[0], oblique().matrix());
}

TEST(MovingMeshes, OnlyTracksWithDifferentKeysMove) {
  Scene scene = animated_scene();
  scene.meshes.push_back(scene.meshes[0]);
  EXPECT_EQ(moving_meshes(scene), (std::vector<bool>{true, false, false}));
  MeshTrack held;
  held.mesh = 2;
  held.keys = {TransformKey{0, oblique()}, TransformKey{5, oblique()}, TransformKey{9, oblique()}};
  MeshTrack one_key;
  one_key.mesh = 1;
  one_key.keys = {TransformKey{3, oblique()}};
  MeshTrack out_of_range;
  out_of_range.mesh = 7;
  out_of_range.keys = {TransformKey{0, oblique()}, TransformKey{5, Transform{}}};
  scene.animation.meshes.push_back(held);
  scene.animation.meshes.push_back(one_key);
  scene.animation.meshes.push_back(out_of_range);
  EXPECT_EQ(moving_meshes(scene), (std::vector<bool>{true, false, false}));
  scene.animation.meshes[1].keys[1].transform.translate.x += 1e-6f;
  EXPECT_EQ(moving_meshes(scene), (std::vector<bool>{true, false, true}));
  scene.animation.meshes.erase(scene.animation.meshes.begin());
  EXPECT_EQ(moving_meshes(scene), (std::vector<bool>{false, false, true}));
}

TEST(Scene, BoundsAndTriangleCountUseThePlacementAtTheFirstFrame) {
  const Scene scene = animated_scene();
  EXPECT_EQ(scene.triangle_count(), 2u);
  const Aabb box = scene.bounds();
  // Mesh 0 at frame 0 holds its first key (translate x by 2); mesh 1 sits at z = -7.
  expect_near(box.lo, {0, 0, -7});
  expect_near(box.hi, {3, 1, 0});
}

TEST(FrameAutomatically, WholeBoundingSphereIsInView) {
  TempDir dir;
  const auto obj = dir.write("box.obj",
                             "v -3 10 -1\nv 5 10 -1\nv 5 14 -1\nv -3 14 2\n"
                             "f 1 2 3\nf 1 3 4\n");
  const Scene scene = load_scene(obj);
  EXPECT_EQ(scene.width, 512);
  EXPECT_EQ(scene.height, 512);
  ASSERT_EQ(scene.lights.size(), 1u);
  EXPECT_EQ(scene.lights[0].color, glm::vec3(1.0f));
  const Aabb box = scene.bounds();
  expect_near(scene.camera.look_at, box.center());
  const glm::dvec3 eye(scene.camera.eye);
  const glm::dvec3 forward = glm::normalize(glm::dvec3(scene.camera.look_at) - eye);
  const double radius = 0.5 * glm::length(glm::dvec3(box.extent()));
  const double distance = glm::length(glm::dvec3(box.center()) - eye);
  const double half_fov = glm::radians(double(scene.camera.vfov_deg)) / 2.0;
  EXPECT_LT(std::asin(radius / distance), half_fov) << "bounding sphere inside the view cone";
  for (int corner = 0; corner < 8; ++corner) {
    const glm::dvec3 p((corner & 1) ? box.hi.x : box.lo.x, (corner & 2) ? box.hi.y : box.lo.y,
                       (corner & 4) ? box.hi.z : box.lo.z);
    EXPECT_LT(std::acos(glm::dot(glm::normalize(p - eye), forward)), half_fov);
  }
  EXPECT_NO_THROW(CameraRays(scene.camera, scene.width, scene.height));
}

TEST(FrameAutomatically, SetResolutionRefitsAnAutomaticCameraOnly) {
  TempDir dir;
  const auto obj = dir.write("wide.obj", "v -10 0 0\nv 10 0 0\nv 0 1 0\nf 1 2 3\n");
  Scene scene = load_scene(obj);
  ASSERT_TRUE(scene.camera_automatic);
  const glm::vec3 square_eye = scene.camera.eye;
  // Portrait: the horizontal field of view is now the narrower one, so the camera moves back
  // until the bounding sphere fits it.
  set_resolution(scene, 200, 800);
  EXPECT_EQ(scene.width, 200);
  EXPECT_EQ(scene.height, 800);
  const double before = glm::length(glm::dvec3(square_eye) - glm::dvec3(scene.camera.look_at));
  const double after = glm::length(glm::dvec3(scene.camera.eye) - glm::dvec3(scene.camera.look_at));
  EXPECT_GT(after, 1.5 * before);

  Scene fixed = load_scene(obj);
  fixed.camera_automatic = false;  // as for a camera given in the file
  const Camera given = fixed.camera;
  set_resolution(fixed, 200, 800);
  EXPECT_EQ(fixed.camera, given);
  EXPECT_THROW(set_resolution(fixed, 0, 10), Error);
}

TEST(FrameAutomatically, SceneTooLargeForTheCameraIsAnError) {
  TempDir dir;
  // Bounding radius 3.4e38: the camera would sit near 1e39, beyond the float range.
  const auto obj = dir.write("huge.obj", "v -3e38 0 0\nv 3e38 0 0\nv 0 3e38 0\nf 1 2 3\n");
  const std::string message = test::error_of([&] { (void)load_scene(obj); });
  EXPECT_NE(message.find("huge.obj: the scene is too large for the automatic camera"),
            std::string::npos)
      << message;
}

TEST(FrameAutomatically, KeepsExistingLights) {
  Scene scene = animated_scene();
  frame_automatically(scene);
  EXPECT_EQ(scene.lights.size(), 1u);
  scene.lights.clear();
  frame_automatically(scene);
  EXPECT_EQ(scene.lights.size(), 1u);
}

TEST(DefaultScene, TriangleCountIsInRange) {
  const Scene scene = default_scene();
  EXPECT_GE(scene.triangle_count(), 30000u);
  EXPECT_LE(scene.triangle_count(), 60000u);
  EXPECT_EQ(scene.width, 640);
  EXPECT_EQ(scene.height, 480);
  EXPECT_EQ(scene.lights.size(), 2u);
  EXPECT_TRUE(scene.source.empty());
  bool any_reflective = false;
  for (const Material& m : scene.materials) any_reflective = any_reflective || m.reflective;
  EXPECT_TRUE(any_reflective);
  for (const Mesh& mesh : scene.meshes) {
    EXPECT_EQ(mesh.dropped_degenerate, 0u) << mesh.name;
    EXPECT_EQ(mesh.material_ids.size(), mesh.triangles.size());
    for (const std::uint32_t id : mesh.material_ids) ASSERT_LT(id, scene.materials.size());
  }
  EXPECT_NO_THROW(CameraRays(scene.camera, scene.width, scene.height));
}

TEST(DefaultScene, IsTheSameBitsEveryCall) {
  const Scene a = default_scene();
  const Scene b = default_scene();
  ASSERT_EQ(a.meshes.size(), b.meshes.size());
  for (std::size_t m = 0; m < a.meshes.size(); ++m) {
    const Mesh& x = a.meshes[m];
    const Mesh& y = b.meshes[m];
    ASSERT_EQ(x.positions.size(), y.positions.size());
    EXPECT_EQ(
        std::memcmp(x.positions.data(), y.positions.data(), x.positions.size() * sizeof(glm::vec3)),
        0);
    EXPECT_EQ(x.normals, y.normals);
    EXPECT_EQ(x.triangles, y.triangles);
    EXPECT_EQ(x.material_ids, y.material_ids);
    EXPECT_EQ(x.world_from_object, y.world_from_object);
  }
  EXPECT_EQ(a.materials, b.materials);
  EXPECT_EQ(a.camera, b.camera);
  EXPECT_EQ(a.lights, b.lights);
  EXPECT_EQ(pose_at(a, 7).world_from_object, pose_at(b, 7).world_from_object);
}

TEST(DefaultScene, SurfacesFaceOutward) {
  const Scene scene = default_scene();
  for (const Mesh& mesh : scene.meshes) {
    if (mesh.normals.empty()) continue;
    for (const glm::uvec3& t : mesh.triangles) {
      const glm::dvec3 a(mesh.positions[t.x]), b(mesh.positions[t.y]), c(mesh.positions[t.z]);
      const glm::dvec3 n = glm::cross(b - a, c - a);
      ASSERT_GT(glm::dot(n, glm::dvec3(mesh.normals[t.x] + mesh.normals[t.y] + mesh.normals[t.z])),
                0.0)
          << mesh.name << ": geometric and shading normals disagree";
    }
  }
  // Floor and boxes have no normals: the floor faces up, each box (24 vertices) faces away
  // from its centre.
  for (const Mesh& mesh : scene.meshes) {
    if (!mesh.normals.empty()) continue;
    for (const glm::uvec3& t : mesh.triangles) {
      const glm::dvec3 a(mesh.positions[t.x]), b(mesh.positions[t.y]), c(mesh.positions[t.z]);
      const glm::dvec3 n = glm::cross(b - a, c - a);
      if (mesh.name == "floor") {
        EXPECT_GT(n.y, 0.0);
        continue;
      }
      glm::dvec3 centre(0.0);
      const std::uint32_t first = t.x / 24 * 24;
      for (std::uint32_t i = first; i < first + 24; ++i)
        centre += glm::dvec3(mesh.positions[i]) / 24.0;
      EXPECT_GT(glm::dot(n, (a + b + c) / 3.0 - centre), 0.0) << mesh.name;
    }
  }
}

TEST(DefaultScene, AnimationMovesOneSphereOnly) {
  const Scene scene = default_scene();
  EXPECT_EQ(scene.animation.frame_begin, 0);
  EXPECT_EQ(scene.animation.frame_end, 23);
  EXPECT_TRUE(scene.animation.camera.empty());
  ASSERT_EQ(scene.animation.meshes.size(), 1u);
  const FramePose first = pose_at(scene, 0);
  const FramePose middle = pose_at(scene, 12);
  int moved = 0;
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    if (first.world_from_object[m] != middle.world_from_object[m]) ++moved;
    EXPECT_EQ(first.world_from_object[m], scene.meshes[m].world_from_object)
        << "frame 0 is the static placement";
  }
  EXPECT_EQ(moved, 1);
  EXPECT_EQ(first.camera, middle.camera);
  EXPECT_EQ(first.lights, middle.lights);
}

/// A one-triangle scene whose camera keys (frames 10 and 20) pass through look_at at frame 15.
Scene camera_through_look_at() {
  Scene scene = test::one_triangle_scene();
  scene.animation.frame_begin = 0;
  scene.animation.frame_end = 30;
  Camera a = scene.camera, b = scene.camera;
  a.look_at = glm::vec3(0.0f);
  b.look_at = glm::vec3(0.0f);
  a.eye = glm::vec3(0, 0, 5);
  b.eye = glm::vec3(0, 0, -5);
  a.up = b.up = glm::vec3(0, 1, 0);
  scene.animation.camera = {CameraKey{10, a}, CameraKey{20, b}};
  return scene;
}

std::string check_cameras_error(const Scene& scene, int first, int last) {
  try {
    check_cameras(scene, first, last, "s.json");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Scene, CheckCamerasNamesTheFirstDegenerateFrame) {
  const Scene scene = camera_through_look_at();
  EXPECT_EQ(camera_at(scene, 15).eye, camera_at(scene, 15).look_at);
  EXPECT_EQ(check_cameras_error(scene, 0, 30), "s.json: frame 15: camera: eye and look_at coincide");
  EXPECT_EQ(check_cameras_error(scene, 15, 15), "s.json: frame 15: camera: eye and look_at coincide");
  // Frames on either side of it, and outside the keys (which hold the nearest key's camera).
  EXPECT_EQ(check_cameras_error(scene, 0, 14), "");
  EXPECT_EQ(check_cameras_error(scene, 16, 30), "");
  EXPECT_EQ(check_cameras_error(scene, 21, 2000000000), "");
  // camera_at is pose_at's camera.
  for (int frame : {0, 12, 15, 19, 25}) EXPECT_EQ(camera_at(scene, frame), pose_at(scene, frame).camera);
}

TEST(Scene, CheckCamerasFindsTheBadFrameOfALongSpan) {
  // Keys a billion frames apart: too many to check one by one, so the frames near where the
  // view is shortest and where up lines up with it are found and checked.
  Scene scene = camera_through_look_at();
  scene.animation.frame_end = 1000000000;
  scene.animation.camera[0].frame = 0;
  scene.animation.camera[1].frame = 1000000000;
  EXPECT_EQ(camera_at(scene, 500000000).eye, camera_at(scene, 500000000).look_at);
  EXPECT_EQ(check_cameras_error(scene, 0, 1000000000), "s.json: frame 500000000: camera: eye and look_at coincide");
  EXPECT_EQ(check_cameras_error(scene, 0, 499999990), "");
  // up swinging from +y to -y through the view direction (-z) at a third of the way.
  Scene turning = test::one_triangle_scene();
  turning.animation.frame_end = 900000000;
  Camera a = turning.camera, b = turning.camera;
  a.eye = b.eye = glm::vec3(0, 0, 5);
  a.look_at = b.look_at = glm::vec3(0.0f);
  a.up = glm::vec3(0, 1, -1);
  b.up = glm::vec3(0, -2, -1);
  turning.animation.camera = {CameraKey{0, a}, CameraKey{900000000, b}};
  EXPECT_EQ(check_cameras_error(turning, 0, 900000000), "s.json: frame 300000000: camera: up is parallel to the view direction");
  // up shrinking through zero without lining up with the view: only its direction matters, so
  // the frames where it is tiny are good; where it is exactly zero, that is the error.
  Scene shrinking = turning;
  shrinking.animation.camera[0].camera.up = glm::vec3(0, 1, 0);
  shrinking.animation.camera[1].camera.up = glm::vec3(0, -2, 0);
  const float tiny_up = camera_at(shrinking, 300000000).up.y;  // 1 - t - 2t in double, t = 1/3
  EXPECT_GT(tiny_up, 0.0f);
  EXPECT_LT(tiny_up, 1e-12f);
  EXPECT_EQ(check_cameras_error(shrinking, 0, 900000000), "");
  // Exactly zero at frame 2e8 of a billion: found without checking every frame.
  Scene zero_up = shrinking;
  zero_up.animation.frame_end = 1000000000;
  zero_up.animation.camera[0].camera.up = glm::vec3(0, 1, 0);
  zero_up.animation.camera[1] = CameraKey{1000000000, zero_up.animation.camera[1].camera};
  zero_up.animation.camera[1].camera.up = glm::vec3(0, -4, 0);
  ASSERT_EQ(camera_at(zero_up, 200000000).up, glm::vec3(0.0f));
  EXPECT_EQ(check_cameras_error(zero_up, 0, 1000000000), "s.json: frame 200000000: camera: up is zero");
  shrinking.animation.camera[1].camera.up = glm::vec3(0, -1, 0);
  shrinking.animation.camera[1].frame = 2;
  EXPECT_EQ(camera_at(shrinking, 1).up, glm::vec3(0.0f));
  EXPECT_EQ(check_cameras_error(shrinking, 0, 2), "s.json: frame 1: camera: up is zero");
}

TEST(Scene, FramesOutsideTheAnimationRangeAreNoted) {
  const Scene scene = camera_through_look_at();  // frames 0-30, camera keys at 10 and 20
  EXPECT_EQ(frames_outside_animation_note(scene, 0, 30), "");
  EXPECT_EQ(frames_outside_animation_note(scene, 7, 7), "");
  EXPECT_EQ(frames_outside_animation_note(scene, 50, 50),
            "frame 50 lies outside the scene's animation (frames 0-30, its range and keys), where every track holds "
            "its nearest key: frames after 30 show frame 30");
  Scene later = scene;
  later.animation.frame_begin = 5;
  EXPECT_EQ(frames_outside_animation_note(later, 0, 40),
            "frames 0-40 reach outside the scene's animation (frames 5-30, its range and keys), where every track "
            "holds its nearest key: frames before 5 show frame 5, frames after 30 show frame 30");
  // Keys past the declared range still move things: the span runs to the last key.
  Scene keyed_later = scene;
  keyed_later.animation.frame_end = 15;  // camera keys at 10 and 20
  EXPECT_EQ(frames_outside_animation_note(keyed_later, 0, 20), "");
  EXPECT_NE(frames_outside_animation_note(keyed_later, 0, 21).find("frames after 20 show frame 20"), std::string::npos);
  // A scene with no track is the same picture at every frame by design: nothing to note.
  EXPECT_EQ(frames_outside_animation_note(test::one_triangle_scene(), 0, 100), "");
  // The default scene's moving sphere is a mesh track.
  EXPECT_NE(frames_outside_animation_note(default_scene(), 0, 24), "");
}

TEST(Scene, CheckCamerasWithoutKeysChecksTheSceneCamera) {
  Scene scene = test::one_triangle_scene();
  EXPECT_EQ(check_cameras_error(scene, 0, 100), "");
  scene.camera.up = glm::normalize(scene.camera.look_at - scene.camera.eye);
  EXPECT_EQ(check_cameras_error(scene, 3, 100), "s.json: frame 3: camera: up is parallel to the view direction");
}

}  // namespace
}  // namespace rtc
