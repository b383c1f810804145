// Wavefront OBJ + MTL loader, hand-written.
//
// Why not tinyobjloader or Assimp: measured on the dev container (2 cores, files in the page
// cache, best of 9 runs, Release -O3, `scene_load_timing 9 <file>` from tests/unit/scene):
//   radiance-cabin.obj (262,425 tris, 8.6 MiB)   this loader 37 ms, tinyobjloader 2.0rc10 81 ms,
//                                                 Assimp 5.2 110 ms
//   spd-balls-s3.obj   (157,442 tris, 10.4 MiB)  this loader 41 ms, tinyobjloader 76 ms,
//                                                 Assimp 112 ms
// (tinyobjloader and Assimp figures are their parse only, before conversion.) Besides speed,
// tinyobjloader 2.0rc10 reads "v nan 0 0" as 0, reports an out-of-range index only as a
// warning naming the file's last line, and parses indices with atoi; this loader rejects every
// bad token with its own line.
//
// Supported: v (extra w / colour values ignored), vn, vt (counted for index checks), f with
// v, v/t, v//n, v/t/n and negative (relative) indices, polygons fan-triangulated from vertex
// 0, usemtl, mtllib (several files per line allowed). o, g, s and display statements are
// skipped quietly; l, p, free-form geometry and unknown keywords are skipped with a warning
// (once per keyword). Indices must refer to vertices defined above the face.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "common/base/error.h"
#include "common/base/log.h"
#include "common/scene/file_bytes.h"
#include "common/scene/material_values.h"
#include "common/scene/mesh_builder.h"
#include "common/scene/mesh_file.h"
#include "common/scene/text_cursor.h"

namespace rtc {
namespace {

namespace fs = std::filesystem;

glm::vec3 read_color(TextCursor& cursor, std::string_view what) {
  const float r = cursor.next_float_on_line(what);
  if (!cursor.more_on_line()) return glm::vec3(r);  // "Kd 0.5" means grey
  const float g = cursor.next_float_on_line(what);
  const float b = cursor.next_float_on_line(what);
  return {r, g, b};
}

/// Reads one MTL file into `materials` (names already present keep their first definition).
void read_mtl(const fs::path& path, std::vector<Material>& materials,
              std::unordered_map<std::string, std::uint32_t>& by_name) {
  const FileBytes bytes(path);
  TextCursor cursor(bytes.view(), path.string());
  Material* current = nullptr;
  Material ignored;  // a redefinition is parsed (and checked) into this
  bool has_d = false;
  for (;;) {
    const std::string_view key = cursor.next_token();
    if (key.empty()) break;
    if (key == "newmtl") {
      const std::string name(cursor.rest_of_line());
      if (name.empty()) cursor.fail("newmtl without a name");
      has_d = false;
      if (by_name.contains(name)) {
        spdlog::warn("{}:{}: material \"{}\" defined again; the first definition is used",
                     path.string(), cursor.line(), name);
        ignored = Material{};
        current = &ignored;
        continue;
      }
      by_name.emplace(name, static_cast<std::uint32_t>(materials.size()));
      materials.emplace_back();
      current = &materials.back();
      current->name = name;
      current->diffuse = glm::vec3(0.8f);
      continue;
    }
    if (current == nullptr) {
      if (key == "Ka" || key == "Kd" || key == "Ks" || key == "Ke" || key == "Ns" || key == "d" ||
          key == "Tr" || key == "illum") {
        cursor.fail(quoted(key) + " before the first newmtl");
      }
      cursor.skip_line();
      continue;
    }
    // Negative colours and shininess would give NaN or negative pixels: clamped with a warning.
    if (key == "Kd" || key == "Ks" || key == "Ke") {
      const glm::vec3 color = read_color(cursor, std::string(key) + " value");
      glm::vec3& slot = key == "Kd"   ? current->diffuse
                        : key == "Ks" ? current->specular
                                      : current->emission;
      slot = checked_color(color, key, cursor.file(), cursor.line());
    } else if (key == "Ns") {
      const float ns = cursor.next_float_on_line("Ns value");
      current->shininess = checked_shininess(ns, "Ns", cursor.file(), cursor.line());
    } else if (key == "d") {
      current->opacity = checked_opacity(cursor.next_float_on_line("d value"), "d", cursor.file(), cursor.line());
      has_d = true;
    } else if (key == "Tr") {
      const float transparency = checked_opacity(cursor.next_float_on_line("Tr value"), "Tr", cursor.file(), cursor.line());
      if (!has_d) current->opacity = 1.0f - transparency;
    } else if (key == "illum") {
      const std::int64_t illum = cursor.next_int("illum value");
      if (illum < 0 || illum > 10) cursor.fail("illum must be 0..10, got " + std::to_string(illum));
      current->reflective = illum == 3;  // the pack's convention: illum 3 = mirror with weight Ks
    }
    cursor.skip_line();  // Ka, Ni, Tf, map_*, and the rest of a handled line
  }
}

/// A parsed face corner: OBJ position and normal index (0-based, normal -1 when absent).
struct Corner {
  std::int64_t v = 0;
  std::int64_t vn = -1;
};

class ObjReader {
 public:
  explicit ObjReader(const fs::path& path)
      : path_(path),
        bytes_(path),
        text_(bytes_.view()),
        cursor_(text_, path.string()),
        builder_(path.stem().string(), path.string()) {
    materials_.emplace_back();  // material 0: the default, for faces before any usemtl
  }

  MeshFile read() {
    // OBJ is text: a NUL byte means another kind of file (a binary PLY or GLB named .obj, say),
    // which would otherwise read as a flood of unknown statements before failing.
    if (const std::size_t nul = text_.find('\0'); nul != std::string_view::npos) {
      const auto line = static_cast<std::uint64_t>(std::count(text_.begin(), text_.begin() + static_cast<std::ptrdiff_t>(nul), '\n'));
      throw_at(path_.string(), line + 1,
               fmt::format("a NUL byte at offset {}: not an OBJ text file (a binary file with an .obj name?)", nul));
    }
    // A rough estimate keeps reallocation off the profile: ~30 bytes per vertex line and
    // ~20 per face line in typical files.
    positions_.reserve(text_.size() / 60);
    for (;;) {
      const std::string_view key = cursor_.next_token();
      if (key.empty()) break;
      if (key == "v") {
        const float x = cursor_.next_float_on_line("vertex x");
        const float y = cursor_.next_float_on_line("vertex y");
        const float z = cursor_.next_float_on_line("vertex z");
        positions_.emplace_back(x, y, z);
        first_out_.push_back(kNone);
        first_normal_.push_back(-1);
      } else if (key == "f") {
        read_face();
      } else if (key == "vn") {
        const float x = cursor_.next_float_on_line("normal x");
        const float y = cursor_.next_float_on_line("normal y");
        const float z = cursor_.next_float_on_line("normal z");
        normals_.emplace_back(x, y, z);
      } else if (key == "vt") {
        ++texcoord_count_;
      } else if (key == "usemtl") {
        use_material(std::string(cursor_.rest_of_line()));
      } else if (key == "mtllib") {
        load_libraries(cursor_.rest_of_line());
      } else if (key != "o" && key != "g" && key != "s" && key != "vp" && key != "#") {
        note_skipped(key);
      }
      cursor_.skip_line();
    }
    MeshFile file;
    file.mesh = builder_.finish();
    file.materials = std::move(materials_);
    return file;
  }

 private:
  static constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

  // Resolves a 1-based or negative (relative) OBJ index against `count` entries.
  std::int64_t resolve(std::int64_t index, std::size_t count, std::string_view what, std::string_view plural,
                       std::string_view token) {
    const auto n = static_cast<std::int64_t>(count);
    const std::int64_t resolved = index > 0 ? index - 1 : n + index;
    if (index == 0 || resolved < 0 || resolved >= n) {
      cursor_.fail(std::string(what) + " index " + std::to_string(index) + " in " + quoted(token) +
                   " out of range (" + std::to_string(count) + " " + std::string(count == 1 ? what : plural) +
                   " defined above)");
    }
    return resolved;
  }

  Corner parse_corner(std::string_view token) {
    Corner corner;
    std::size_t slash = token.find('/');
    std::int64_t value = 0;
    if (!parse_int(token.substr(0, slash), value)) cursor_.fail("bad face vertex " + quoted(token));
    corner.v = resolve(value, positions_.size(), "vertex", "vertices", token);
    if (slash == std::string_view::npos) return corner;
    std::string_view rest = token.substr(slash + 1);
    slash = rest.find('/');
    const std::string_view texcoord = rest.substr(0, slash);
    if (!texcoord.empty()) {
      if (!parse_int(texcoord, value)) cursor_.fail("bad face vertex " + quoted(token));
      resolve(value, texcoord_count_, "texture coordinate", "texture coordinates", token);
    }
    if (slash == std::string_view::npos) return corner;
    const std::string_view normal = rest.substr(slash + 1);
    if (!parse_int(normal, value)) cursor_.fail("bad face vertex " + quoted(token));
    corner.vn = resolve(value, normals_.size(), "normal", "normals", token);
    return corner;
  }

  // The mesh vertex for an OBJ (position, normal) pair; most positions come with one normal
  // only, so a per-position slot serves them and a map the rest.
  std::uint32_t vertex_for(const Corner& corner) {
    const auto v = static_cast<std::size_t>(corner.v);
    if (first_out_[v] == kNone) {
      first_normal_[v] = corner.vn;
      first_out_[v] = add_vertex(corner);
      return first_out_[v];
    }
    if (first_normal_[v] == corner.vn) return first_out_[v];
    const std::uint64_t key =
        (static_cast<std::uint64_t>(v) << 32) ^ static_cast<std::uint64_t>(corner.vn + 1);
    const auto [it, inserted] = other_pairs_.try_emplace(key, 0);
    if (inserted) it->second = add_vertex(corner);
    return it->second;
  }

  std::uint32_t add_vertex(const Corner& corner) {
    const glm::vec3& p = positions_[static_cast<std::size_t>(corner.v)];
    if (corner.vn < 0) return builder_.add_vertex(p);
    return builder_.add_vertex(p, normals_[static_cast<std::size_t>(corner.vn)]);
  }

  void read_face() {
    polygon_.clear();
    for (;;) {
      const std::string_view token = cursor_.next_token_on_line();
      if (token.empty()) break;
      polygon_.push_back(vertex_for(parse_corner(token)));
    }
    if (polygon_.size() < 3) {
      cursor_.fail("face with " + std::to_string(polygon_.size()) +
                   " vertices (a face needs at least 3)");
    }
    for (std::size_t k = 1; k + 1 < polygon_.size(); ++k) {
      builder_.add_triangle(polygon_[0], polygon_[k], polygon_[k + 1]);
    }
  }

  void use_material(const std::string& name) {
    const auto it = material_by_name_.find(name);
    if (it != material_by_name_.end()) {
      builder_.set_material(it->second);
      return;
    }
    if (warned_materials_.insert(name).second && !missing_library_) {
      spdlog::warn("{}:{}: material \"{}\" is not in any loaded .mtl; using the default material",
                   path_.string(), cursor_.line(), name);
    }
    builder_.set_material(0);
  }

  void load_libraries(std::string_view names) {
    if (names.empty()) cursor_.fail("mtllib without a file name");
    // (No NUL byte: read() refuses a file with one.)
    const fs::path folder = path_.parent_path();
    std::vector<std::string> files;
    std::error_code ec;
    if (fs::exists(folder / std::string(names), ec)) {
      files.emplace_back(names);  // a single name with spaces
    } else {
      TextCursor words(names, path_.string(), false);
      for (std::string_view w = words.next_token(); !w.empty(); w = words.next_token()) {
        files.emplace_back(w);
      }
    }
    for (const std::string& name : files) {
      const fs::path mtl = folder / name;
      if (!fs::exists(mtl, ec)) {
        spdlog::warn("{}:{}: material library {} not found; its materials become the default",
                     path_.string(), cursor_.line(), mtl.string());
        missing_library_ = true;
        continue;
      }
      try {
        read_mtl(mtl, materials_, material_by_name_);
      } catch (const Error& e) {
        cursor_.fail(std::string("material library: ") + e.what());  // where the OBJ names it
      }
    }
  }

  /// The first time a statement rtc does not read comes up in the file. Grouping, display and
  /// texture-map statements change nothing rtc draws (debug); lines, points and free-form
  /// curves and surfaces are geometry left out (rtc draws triangles), and a keyword outside the
  /// OBJ format may be a typo or another format (both warned, with the line).
  void note_skipped(std::string_view key) {
    static const std::unordered_set<std::string_view> kNoGeometry = {
        "mg", "lod", "bevel", "c_interp", "d_interp", "usemap", "maplib", "shadow_obj", "trace_obj",
        "ctech", "stech", "call", "csh"};
    static const std::unordered_set<std::string_view> kFreeForm = {
        "curv", "curv2", "surf", "cstype", "deg", "bmat", "step", "parm", "trim", "hole", "scrv", "sp", "end", "con"};
    // One note per keyword, and one for the whole free-form family (a curve takes five statements).
    const bool free_form = kFreeForm.count(key) > 0;
    if (!skipped_keys_.insert(free_form ? std::string("free-form") : std::string(key)).second) return;
    if (kNoGeometry.count(key) > 0) {
      spdlog::debug("{}:{}: OBJ statement {} skipped (it draws nothing)", path_.string(), cursor_.line(), quoted(key));
    } else if (free_form || key == "l" || key == "p") {
      spdlog::warn("{}:{}: OBJ statement {} skipped{}, here and below: rtc draws faces (f) only, not lines, points or "
                   "free-form curves and surfaces",
                   path_.string(), cursor_.line(), quoted(key), free_form ? " with the other free-form statements" : "");
    } else if (++unknown_keys_ <= kMaxUnknownKeysSaid) {
      spdlog::warn("{}:{}: unknown OBJ statement {} skipped, here and below{}", path_.string(), cursor_.line(),
                   quoted(key),
                   unknown_keys_ == kMaxUnknownKeysSaid ? "; further unknown statements are skipped unsaid (is this an OBJ file?)"
                                                        : "");
    }
  }

  fs::path path_;
  FileBytes bytes_;
  std::string_view text_;
  TextCursor cursor_;
  MeshBuilder builder_;
  std::vector<glm::vec3> positions_;
  std::vector<glm::vec3> normals_;
  std::size_t texcoord_count_ = 0;
  std::vector<std::uint32_t> first_out_;
  std::vector<std::int64_t> first_normal_;
  std::unordered_map<std::uint64_t, std::uint32_t> other_pairs_;
  std::vector<std::uint32_t> polygon_;
  std::vector<Material> materials_;
  std::unordered_map<std::string, std::uint32_t> material_by_name_;
  std::unordered_set<std::string> warned_materials_;
  std::unordered_set<std::string> skipped_keys_;
  static constexpr int kMaxUnknownKeysSaid = 10;
  int unknown_keys_ = 0;
  bool missing_library_ = false;
};

}  // namespace

MeshFile load_obj(const std::filesystem::path& path) { return ObjReader(path).read(); }

}  // namespace rtc
