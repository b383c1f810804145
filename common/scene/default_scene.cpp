// The procedural scene compiled into the program: a checkered floor, three mirror-like spheres
// (one of them animated), a torus, two boxes and a pillar; about 38k triangles, two lights.
// Angles go through det_math, so the scene is the same bits on every CPU.
#include <cmath>
#include <string>

#include "common/math/det_math.h"
#include "common/scene/load.h"
#include "common/scene/load_internal.h"
#include "common/scene/mesh_builder.h"
#include "common/scene/tessellate.h"

namespace rtc {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr const char* kSource = "default_scene";

Material make_material(const char* name, glm::vec3 diffuse, glm::vec3 specular, float shininess,
                       bool reflective) {
  Material m;
  m.name = name;
  m.diffuse = diffuse;
  m.specular = specular;
  m.shininess = shininess;
  m.reflective = reflective;
  return m;
}

/// 2n x 2n unit tiles centred on the origin at y = 0, alternating materials 0 and 1.
Mesh make_floor(int n) {
  MeshBuilder builder("floor", kSource);
  for (int z = -n; z < n; ++z) {
    for (int x = -n; x < n; ++x) {
      const auto fx = static_cast<float>(x), fz = static_cast<float>(z);
      const std::uint32_t a = builder.add_vertex({fx, 0.0f, fz});
      const std::uint32_t b = builder.add_vertex({fx, 0.0f, fz + 1.0f});
      const std::uint32_t c = builder.add_vertex({fx + 1.0f, 0.0f, fz + 1.0f});
      const std::uint32_t d = builder.add_vertex({fx + 1.0f, 0.0f, fz});
      builder.set_material(static_cast<std::uint32_t>((x + z) & 1));
      builder.add_triangle(a, b, c);  // counter-clockwise seen from +y
      builder.add_triangle(a, c, d);
    }
  }
  return builder.finish();
}

Mesh make_sphere(const char* name, int quads) {
  MeshBuilder builder(name, kSource);
  append_sphere(builder, make_cube_sphere(quads), glm::dvec3(0.0), 1.0);
  return builder.finish();
}

/// Torus around the y axis: major radius `major`, tube radius `minor`.
Mesh make_torus(double major, double minor, int around, int tube) {
  MeshBuilder builder("torus", kSource);
  for (int i = 0; i < around; ++i) {
    const double u = 2.0 * kPi * i / around;
    for (int j = 0; j < tube; ++j) {
      const double v = 2.0 * kPi * j / tube;
      const double cos_u = det_cos(u), sin_u = det_sin(u), cos_v = det_cos(v);
      const glm::dvec3 normal(cos_v * cos_u, det_sin(v), cos_v * sin_u);
      const glm::dvec3 center(major * cos_u, 0.0, major * sin_u);
      builder.add_vertex(glm::vec3(center + minor * normal), glm::vec3(normal));
    }
  }
  auto at = [&](int i, int j) {
    return static_cast<std::uint32_t>((i % around) * tube + (j % tube));
  };
  for (int i = 0; i < around; ++i) {
    for (int j = 0; j < tube; ++j) {
      // (u, v) runs clockwise seen from outside, so the quad is wound v first.
      builder.add_triangle(at(i, j), at(i, j + 1), at(i + 1, j + 1));
      builder.add_triangle(at(i, j), at(i + 1, j + 1), at(i + 1, j));
    }
  }
  return builder.finish();
}

/// Axis-aligned box from `lo` to `hi`, flat faces wound counter-clockwise from outside.
void append_box(MeshBuilder& builder, glm::vec3 lo, glm::vec3 hi) {
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + (side == 1 ? 1 : 2)) % 3;
      const int v = (axis + (side == 1 ? 2 : 1)) % 3;
      glm::vec3 corner[4];
      for (int k = 0; k < 4; ++k) {
        glm::vec3 p;
        p[axis] = side == 1 ? hi[axis] : lo[axis];
        p[u] = (k == 1 || k == 2) ? hi[u] : lo[u];
        p[v] = (k >= 2) ? hi[v] : lo[v];
        corner[k] = p;
      }
      const std::uint32_t a = builder.add_vertex(corner[0]);
      const std::uint32_t b = builder.add_vertex(corner[1]);
      const std::uint32_t c = builder.add_vertex(corner[2]);
      const std::uint32_t d = builder.add_vertex(corner[3]);
      builder.add_triangle(a, b, c);
      builder.add_triangle(a, c, d);
    }
  }
}

Transform placed(glm::vec3 translate, float degrees_about_y = 0.0f,
                 glm::vec3 scale = glm::vec3(1.0f)) {
  Transform t;
  t.translate = translate;
  const glm::dquat q =
      rotation_deg_axis(static_cast<double>(degrees_about_y), glm::dvec3(0.0, 1.0, 0.0));
  t.rotate = glm::quat(static_cast<float>(q.w), static_cast<float>(q.x), static_cast<float>(q.y),
                       static_cast<float>(q.z));
  t.scale = scale;
  return t;
}

std::uint32_t add(Scene& scene, Mesh mesh, const std::vector<Material>& materials,
                  const Transform& transform) {
  mesh.world_from_object = transform.matrix();
  return append_mesh(scene, std::move(mesh), materials);
}

}  // namespace

Scene default_scene() {
  Scene scene;
  scene.name = "default";
  scene.width = 640;
  scene.height = 480;
  scene.background = glm::vec3(0.10f, 0.13f, 0.22f);
  scene.ambient = glm::vec3(0.08f);
  scene.materials.emplace_back();

  const Material light_tile =
      make_material("floor_light", {0.85f, 0.85f, 0.80f}, glm::vec3(0.0f), 32.0f, false);
  const Material dark_tile =
      make_material("floor_dark", {0.12f, 0.12f, 0.16f}, glm::vec3(0.0f), 32.0f, false);
  const Material mirror = make_material("mirror", glm::vec3(0.05f), glm::vec3(0.9f), 500.0f, true);
  const Material gold =
      make_material("gold", {0.35f, 0.25f, 0.08f}, {0.65f, 0.55f, 0.25f}, 200.0f, true);
  const Material blue =
      make_material("blue_glaze", {0.10f, 0.20f, 0.60f}, glm::vec3(0.3f), 100.0f, true);
  const Material red =
      make_material("red_plastic", {0.70f, 0.10f, 0.08f}, glm::vec3(0.25f), 60.0f, false);
  const Material green =
      make_material("green_matte", {0.15f, 0.55f, 0.20f}, glm::vec3(0.0f), 32.0f, false);
  const Material white =
      make_material("white_matte", glm::vec3(0.75f), glm::vec3(0.0f), 32.0f, false);

  add(scene, make_floor(10), {light_tile, dark_tile}, Transform{});
  // 24 x 24 quads per cube face: 6,912 triangles per sphere.
  add(scene, make_sphere("mirror_sphere", 24), {mirror}, placed({-2.3f, 1.0f, -0.5f}));
  add(scene, make_sphere("blue_sphere", 24), {blue},
      placed({0.4f, 0.7f, -2.6f}, 0.0f, glm::vec3(0.7f)));
  const std::uint32_t moving = add(scene, make_sphere("gold_sphere", 24), {gold},
                                   placed({2.4f, 0.8f, -0.2f}, 0.0f, glm::vec3(0.8f)));
  add(scene, make_torus(0.9, 0.3, 128, 64), {red}, placed({0.0f, 0.3f, 1.6f}, 20.0f));
  {
    MeshBuilder builder("boxes", kSource);
    append_box(builder, {-0.5f, 0.0f, -0.5f}, {0.5f, 1.0f, 0.5f});
    append_box(builder, {-0.4f, 1.0f, -0.4f}, {0.4f, 1.6f, 0.4f});
    add(scene, builder.finish(), {green}, placed({-2.9f, 0.0f, 1.8f}, 30.0f));
  }
  {
    MeshBuilder builder("pillar", kSource);
    append_cone(builder, glm::dvec3(0.0), 0.35, glm::dvec3(0.0, 2.5, 0.0), 0.25, 64);
    add(scene, builder.finish(), {white}, placed({3.8f, 0.0f, -3.0f}));
  }

  scene.lights.push_back(PointLight{{-5.0f, 8.0f, 6.0f}, glm::vec3(0.75f)});
  scene.lights.push_back(PointLight{{6.0f, 6.0f, -2.0f}, glm::vec3(0.45f)});
  scene.camera.eye = {0.0f, 3.4f, 9.0f};
  scene.camera.look_at = {0.0f, 0.8f, 0.0f};
  scene.camera.up = {0.0f, 1.0f, 0.0f};
  scene.camera.vfov_deg = 40.0f;

  // Frames 0-23: the gold sphere hops forward and spins; camera and lights stay.
  scene.animation.frame_begin = 0;
  scene.animation.frame_end = 23;
  MeshTrack track;
  track.mesh = moving;
  const Transform start = placed({2.4f, 0.8f, -0.2f}, 0.0f, glm::vec3(0.8f));
  const Transform top = placed({2.4f, 2.0f, 0.8f}, 90.0f, glm::vec3(0.8f));
  const Transform end = placed({2.4f, 0.8f, 1.8f}, 180.0f, glm::vec3(0.8f));
  track.keys = {TransformKey{0, start}, TransformKey{12, top}, TransformKey{23, end}};
  scene.animation.meshes.push_back(track);
  return scene;
}

}  // namespace rtc
