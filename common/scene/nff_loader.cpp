// NFF loader (Eric Haines' Neutral File Format, as written by SPD 3.14), tessellating curved
// primitives the way the scene pack did.
//
// Statements: v (from, at, up, angle, hither, resolution), b, l (optional colour), f, c (the
// one-line SPD 3.14 form and the three-line NFF.TXT form: both are 8 numbers, read across line
// ends), s, p, pp, and # comments.
//   - f r g b Kd Ks Shine T ior: diffuse = Kd * rgb, specular = Ks (white), shininess = Shine,
//     reflective when Ks > 0 (SPD: Ks is also the mirror weight), opacity = 1 - T. Identical f
//     lines share one material (spd-rings repeats them per object).
//   - l without a colour gets sqrt(n) / (2n) for n lights in the file (SPD's suggestion, used
//     by the pack's view.json files).
//   - p: fan from vertex 0 when convex, ear clipping when concave (spd-gears); winding kept.
//   - s: cube-sphere, c: open cone (see Tessellation).
//
// Measured (dev container, Release, page cache, best of 9): spd-balls.nff (7,381 spheres ->
// 1,417,154 triangles) 21.5 ms; spd-gears.nff (9,345 polygons, 128 of them concave ->
// 36,610 triangles) 12.1 ms. Triangle counts, surface areas and bounds equal the pack's
// OBJ/PLY for every SPD scene (ScenePack.NffTessellationMatchesThePackMeshes); polygon and
// patch triangles come out in the pack's order, sphere and cone triangles in another order.
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common/base/error.h"
#include "common/base/log.h"
#include "common/scene/file_bytes.h"
#include "common/scene/material_values.h"
#include "common/scene/mesh_builder.h"
#include "common/scene/mesh_file.h"
#include "common/scene/tessellate.h"
#include "common/scene/text_cursor.h"

namespace rtc {
namespace {

class NffReader {
 public:
  NffReader(const std::filesystem::path& path, const Tessellation& tessellation)
      : bytes_(path),
        text_(bytes_.view()),
        cursor_(text_, path.string()),
        builder_(path.stem().string(), path.string()),
        tessellation_(tessellation) {
    if (tessellation.sphere_quads < Tessellation::kMinSphereQuads ||
        tessellation.sphere_quads > Tessellation::kMaxSphereQuads) {
      throw Error(fmt::format("tessellation: sphere_quads must be in [{}, {}], got {}",
                              Tessellation::kMinSphereQuads, Tessellation::kMaxSphereQuads,
                              tessellation.sphere_quads));
    }
    if (tessellation.cone_segments < Tessellation::kMinConeSegments ||
        tessellation.cone_segments > Tessellation::kMaxConeSegments) {
      throw Error(fmt::format("tessellation: cone_segments must be in [{}, {}], got {}",
                              Tessellation::kMinConeSegments, Tessellation::kMaxConeSegments,
                              tessellation.cone_segments));
    }
    const auto magic = [&](std::string_view m) { return text_.compare(0, m.size(), m) == 0; };
    if (magic("\x1f\x8b") || magic("\xfd"
                                   "7zXZ")) {
      throw_at(path.string(), 0,
               "compressed NFF; decompress it first (gunzip -k / xz -dk) and load the .nff");
    }
    file_.materials.emplace_back();  // material 0 for primitives before the first f
  }

  MeshFile read() {
    for (;;) {
      const std::string_view key = cursor_.next_token();
      if (key.empty()) break;
      if (key == "s") {
        read_sphere();
      } else if (key == "p") {
        read_polygon(false);
      } else if (key == "pp") {
        read_polygon(true);
      } else if (key == "c") {
        read_cone();
      } else if (key == "f") {
        read_fill();
      } else if (key == "l") {
        read_light();
      } else if (key == "v") {
        read_view();
      } else if (key == "b") {
        glm::vec3 background;
        for (int a = 0; a < 3; ++a) background[a] = cursor_.next_float_on_line("background colour");
        file_.background = checked_color(background, "background colour", cursor_.file(), cursor_.line());
      } else {
        cursor_.fail("unknown NFF statement " + quoted(key));
      }
    }
    // Lights without a colour: SPD's suggested relative intensity sqrt(n) / (2n).
    const float n = static_cast<float>(file_.lights.size());
    for (std::size_t i = 0; i < file_.lights.size(); ++i) {
      if (!light_has_color_[i]) file_.lights[i].color = glm::vec3(std::sqrt(n) / (2.0f * n));
    }
    file_.mesh = builder_.finish();
    return std::move(file_);
  }

 private:
  glm::vec3 read_point(std::string_view what) {
    glm::vec3 p;
    for (int a = 0; a < 3; ++a) p[a] = cursor_.next_float(what);
    return p;
  }

  /// Three numbers on one line: the first on the next line when `new_line` (else on this one),
  /// the others on the same line.
  glm::vec3 read_line_point(std::string_view what, bool new_line) {
    glm::vec3 p;
    p[0] = new_line ? cursor_.next_float(what) : cursor_.next_float_on_line(what);
    p[1] = cursor_.next_float_on_line(what);
    p[2] = cursor_.next_float_on_line(what);
    return p;
  }

  /// Fails unless a ball of `radius` around `center` lies within kMaxWorldCoordinate (a
  /// finite centre and radius may still give vertices beyond the float range).
  void check_reach(const glm::vec3& center, float radius, std::string_view what) const {
    for (int a = 0; a < 3; ++a) {
      if (std::abs(static_cast<double>(center[a])) + static_cast<double>(radius) >
          kMaxWorldCoordinate) {
        cursor_.fail(fmt::format("{} ({}, {}, {}) with radius {} reaches beyond the float range "
                                 "(|coordinate| > {})",
                                 what, center.x, center.y, center.z, radius, kMaxWorldCoordinate));
      }
    }
  }

  void read_sphere() {
    const glm::vec3 center = read_point("sphere centre");
    const float radius = cursor_.next_float("sphere radius");
    if (!(radius > 0.0f))
      cursor_.fail("sphere radius must be positive, got " + std::to_string(radius));
    check_reach(center, radius, "sphere centre");
    if (sphere_.points.empty()) sphere_ = make_cube_sphere(tessellation_.sphere_quads);
    append_sphere(builder_, sphere_, glm::dvec3(center), radius);
  }

  void read_cone() {
    // One-line (SPD 3.14) and three-line (NFF.TXT) forms are the same 8 numbers.
    const glm::vec3 base = read_point("cone base");
    const float base_radius = cursor_.next_float("cone base radius");
    const glm::vec3 apex = read_point("cone apex");
    const float apex_radius = cursor_.next_float("cone apex radius");
    if (base_radius < 0.0f || apex_radius < 0.0f) cursor_.fail("cone radius must not be negative");
    check_reach(base, base_radius, "cone base");
    check_reach(apex, apex_radius, "cone apex");
    append_cone(builder_, glm::dvec3(base), base_radius, glm::dvec3(apex), apex_radius,
                tessellation_.cone_segments);
  }

  void read_polygon(bool with_normals) {
    const std::int64_t count = cursor_.next_int("polygon vertex count");
    const std::size_t per_vertex = with_normals ? 6 : 3;
    // Each number takes at least two bytes: bounds the count before allocating.
    if (count < 3 || static_cast<std::uint64_t>(count) >
                         (text_.size() - cursor_.offset()) / (2 * per_vertex) + 1) {
      cursor_.fail("bad polygon vertex count " + std::to_string(count) +
                   (count < 3 ? " (a polygon needs at least 3)" : " (truncated file?)"));
    }
    polygon_.clear();
    const std::uint32_t first = builder_.vertex_count();
    // A vertex per line (its normal beside it in a patch): a line cut short is named as such,
    // not as a bad number on a later line.
    for (std::int64_t k = 0; k < count; ++k) {
      const glm::vec3 p = read_line_point("polygon vertex", /*new_line=*/true);
      polygon_.push_back(p);
      if (with_normals) {
        builder_.add_vertex(p, read_line_point("patch normal", /*new_line=*/false));
      } else {
        builder_.add_vertex(p);
      }
    }
    for (const glm::uvec3& t : triangulate_polygon(polygon_)) {
      builder_.add_triangle(first + t.x, first + t.y, first + t.z);
    }
  }

  void read_fill() {
    float v[8];
    static const char* const kNames[8] = {"fill red", "fill green", "fill blue", "fill Kd",
                                          "fill Ks",  "fill Shine", "fill T",    "fill ior"};
    for (int i = 0; i < 8; ++i) v[i] = cursor_.next_float_on_line(kNames[i]);
    const std::array<float, 8> key{v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]};
    const auto [it, inserted] =
        fill_ids_.try_emplace(key, static_cast<std::uint32_t>(file_.materials.size()));
    if (inserted) {
      Material m;
      m.name = "nff" + std::to_string(fill_ids_.size() - 1);
      // Kd * rgb may overflow to infinity; negative values would give NaN or negative pixels.
      m.diffuse = checked_color(v[3] * glm::vec3(v[0], v[1], v[2]), "fill Kd * colour",
                                cursor_.file(), cursor_.line());
      m.specular = checked_color(glm::vec3(v[4]), "fill Ks", cursor_.file(), cursor_.line());
      m.shininess = checked_shininess(v[5], "fill Shine", cursor_.file(), cursor_.line());
      m.reflective = m.specular.x > 0.0f;
      m.opacity = 1.0f - checked_opacity(v[6], "fill T", cursor_.file(), cursor_.line());
      file_.materials.push_back(m);
    }
    builder_.set_material(it->second);
  }

  void read_light() {
    PointLight light;
    for (int a = 0; a < 3; ++a) light.position[a] = cursor_.next_float_on_line("light position");
    const bool has_color = cursor_.more_on_line();
    if (has_color) {
      for (int a = 0; a < 3; ++a) light.color[a] = cursor_.next_float_on_line("light colour");
      light.color = checked_color(light.color, "light colour", cursor_.file(), cursor_.line());
    }
    file_.lights.push_back(light);
    light_has_color_.push_back(has_color);
  }

  void read_view() {
    // SPD files give one view; where another follows, it replaces the first, as it always did,
    // but not silently.
    if (view_line_ != 0) {
      spdlog::warn("{}", at_location(cursor_.file(), cursor_.line(),
                                     fmt::format("a second view block replaces the one at line {}", view_line_)));
    }
    view_line_ = cursor_.line();
    Camera camera;
    glm::ivec2 resolution(512, 512);
    bool seen[6] = {};
    static const char* const kKeys[6] = {"from", "at", "up", "angle", "hither", "resolution"};
    for (;;) {
      const std::string_view key = cursor_.peek_token();
      int which = -1;
      for (int k = 0; k < 6; ++k) {
        if (key == kKeys[k]) which = k;
      }
      if (which < 0) break;
      cursor_.next_token();
      if (seen[which]) cursor_.fail(std::string("view block gives \"") + kKeys[which] + "\" twice");
      seen[which] = true;
      switch (which) {
        case 0:
          camera.eye = read_point("view from");
          break;
        case 1:
          camera.look_at = read_point("view at");
          break;
        case 2:
          camera.up = read_point("view up");
          break;
        case 3: {
          camera.vfov_deg = cursor_.next_float("view angle");
          if (!(camera.vfov_deg > 0.0f && camera.vfov_deg < 180.0f)) {
            cursor_.fail("view angle must be in (0, 180) degrees");
          }
          break;
        }
        case 4:
          cursor_.next_float("view hither");
          break;  // no near plane in this tracer
        default: {
          for (int a = 0; a < 2; ++a) {
            const std::int64_t r = cursor_.next_int("view resolution");
            if (r <= 0 || r > 65536) cursor_.fail("view resolution must be in [1, 65536]");
            resolution[a] = static_cast<int>(r);
          }
        }
      }
    }
    for (int k = 0; k < 4; ++k) {
      if (!seen[k]) cursor_.fail(std::string("view block without \"") + kKeys[k] + "\"");
    }
    file_.camera = camera;
    if (seen[5]) file_.resolution = resolution;
  }

  FileBytes bytes_;
  std::string_view text_;
  TextCursor cursor_;
  MeshBuilder builder_;
  Tessellation tessellation_;
  MeshFile file_;
  SphereTemplate sphere_;
  std::vector<glm::vec3> polygon_;
  std::map<std::array<float, 8>, std::uint32_t> fill_ids_;
  std::vector<bool> light_has_color_;
  std::uint64_t view_line_ = 0;  // the last view block's line, 0 before the first
};

}  // namespace

MeshFile load_nff(const std::filesystem::path& path, const Tessellation& tessellation) {
  return NffReader(path, tessellation).read();
}

}  // namespace rtc
