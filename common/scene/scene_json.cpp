// The scene JSON format (docs/scene-format.md): a strict superset of the scene pack's
// view.json. Every field is checked for type, length and finiteness, and unknown fields are
// rejected with their full path, e.g. `scene.json: unknown field "animation.meshes[0].keyz"`.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/base/error.h"
#include "common/base/log.h"
#include "common/scene/file_bytes.h"
#include "common/scene/load_internal.h"
#include "common/scene/mesh_file.h"
#include "common/scene/text_cursor.h"

namespace rtc {
namespace {

using Json = nlohmann::json;
namespace fs = std::filesystem;

std::string child(const std::string& path, std::string_view key) {
  return path.empty() ? std::string(key) : path + "." + std::string(key);
}

std::string element(const std::string& path, std::size_t i) {
  return path + "[" + std::to_string(i) + "]";
}

/// The largest |component|; NaN when any component is NaN.
template <typename Vec>
double max_abs(const Vec& v) {
  double m = 0.0;
  for (int a = 0; a < Vec::length(); ++a) {
    const double c = std::abs(static_cast<double>(v[a]));
    if (std::isnan(c)) return c;
    m = std::max(m, c);
  }
  return m;
}

/// Per axis, the largest |object-space coordinate| of the mesh's vertices.
glm::dvec3 object_reach(const Mesh& mesh) {
  glm::dvec3 reach(0.0);
  for (const glm::vec3& p : mesh.positions) reach = glm::max(reach, glm::abs(glm::dvec3(p)));
  return reach;
}

/// An upper bound on |world coordinate| for a mesh of `reach` under `transform`, whatever its
/// rotation: |R S p|_i <= sum_j |s_j| |p_j|. The bound is convex in translate and scale, which
/// pose_at interpolates linearly, so keys within the limit keep every frame between them
/// within it too.
double world_reach(const Transform& transform, const glm::dvec3& reach) {
  const glm::dvec3 s = glm::abs(glm::dvec3(transform.scale));
  return max_abs(glm::dvec3(transform.translate)) + s.x * reach.x + s.y * reach.y + s.z * reach.z;
}

std::string type_name(const Json& j) {
  switch (j.type()) {
    case Json::value_t::null:
      return "null";
    case Json::value_t::object:
      return "an object";
    case Json::value_t::array:
      return "an array";
    case Json::value_t::string:
      return "a string";
    case Json::value_t::boolean:
      return "a boolean";
    case Json::value_t::number_integer:
    case Json::value_t::number_unsigned:
      return "an integer";
    case Json::value_t::number_float:
      return "a number";
    default:
      return "an unsupported value";
  }
}

/// Reads JSON values with the file name and field path in every message.
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& message) const {
    throw Error(file_ + ": field \"" + path + "\": " + message);
  }

  void expect_object(const Json& j, const std::string& path,
                     std::initializer_list<std::string_view> allowed) const {
    if (!j.is_object()) fail(path, "expected an object, got " + type_name(j));
    for (const auto& [key, value] : j.items()) {
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
        throw Error(file_ + ": unknown field \"" + child(path, key) + "\"");
      }
    }
  }

  const Json& required(const Json& obj, const std::string& path, std::string_view key) const {
    const auto it = obj.find(key);
    if (it == obj.end()) {
      throw Error(file_ + ": missing field \"" + child(path, key) + "\"");
    }
    return *it;
  }

  const Json* optional(const Json& obj, std::string_view key) const {
    const auto it = obj.find(key);
    return it == obj.end() ? nullptr : &*it;
  }

  double number(const Json& j, const std::string& path) const {
    if (!j.is_number()) fail(path, "expected a number, got " + type_name(j));
    const double v = j.get<double>();
    if (!std::isfinite(v)) fail(path, "expected a finite number");
    return v;
  }

  float real(const Json& j, const std::string& path) const {
    const double v = number(j, path);
    if (std::abs(v) > std::numeric_limits<float>::max()) fail(path, "number out of float range");
    return static_cast<float>(v);
  }

  std::int64_t integer(const Json& j, const std::string& path, std::int64_t lo,
                       std::int64_t hi) const {
    std::int64_t v = 0;
    if (j.is_number_integer()) {
      if (j.is_number_unsigned() &&
          j.get<std::uint64_t>() >
              static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
        fail(path, "integer out of range");
      }
      v = j.get<std::int64_t>();
    } else if (j.is_number_float() && std::isfinite(j.get<double>()) &&
               std::floor(j.get<double>()) == j.get<double>() && std::abs(j.get<double>()) < 9e15) {
      v = static_cast<std::int64_t>(j.get<double>());  // 512.0 is accepted as 512
    } else if (j.is_number()) {
      fail(path, "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + j.dump());
    } else {
      fail(path, "expected an integer, got " + type_name(j));
    }
    if (v < lo || v > hi) {
      fail(path, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
                     std::to_string(v));
    }
    return v;
  }

  std::string string(const Json& j, const std::string& path) const {
    if (!j.is_string()) fail(path, "expected a string, got " + type_name(j));
    return j.get<std::string>();
  }

  bool boolean(const Json& j, const std::string& path) const {
    if (!j.is_boolean()) fail(path, "expected true or false, got " + type_name(j));
    return j.get<bool>();
  }

  const Json& array(const Json& j, const std::string& path, std::size_t length = 0) const {
    if (!j.is_array()) fail(path, "expected an array, got " + type_name(j));
    if (length > 0 && j.size() != length) {
      fail(path,
           "expected " + std::to_string(length) + " elements, got " + std::to_string(j.size()));
    }
    return j;
  }

  glm::vec3 vec3(const Json& j, const std::string& path) const {
    if (!j.is_array() || j.size() != 3) {
      fail(path, "expected an array of 3 numbers, got " +
                     (j.is_array() ? std::to_string(j.size()) + " elements" : type_name(j)));
    }
    glm::vec3 v;
    for (int a = 0; a < 3; ++a) v[a] = real(j[a], element(path, a));
    return v;
  }

  /// A colour: 3 numbers, none negative (negative colours give negative or NaN pixels).
  glm::vec3 color(const Json& j, const std::string& path) const {
    const glm::vec3 out = vec3(j, path);
    if (out.x < 0.0f || out.y < 0.0f || out.z < 0.0f) {
      fail(path, fmt::format("colour components must not be negative, got [{}, {}, {}]", out.x, out.y, out.z));
    }
    return out;
  }

  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

Camera read_camera_fields(const Reader& r, const Json& j, const std::string& path, Camera camera) {
  if (const Json* v = r.optional(j, "eye")) camera.eye = r.vec3(*v, child(path, "eye"));
  if (const Json* v = r.optional(j, "look_at")) camera.look_at = r.vec3(*v, child(path, "look_at"));
  if (const Json* v = r.optional(j, "up")) camera.up = r.vec3(*v, child(path, "up"));
  if (const Json* v = r.optional(j, "vfov_deg")) {
    camera.vfov_deg = r.real(*v, child(path, "vfov_deg"));
    if (!(camera.vfov_deg > 0.0f && camera.vfov_deg < 180.0f)) {
      r.fail(child(path, "vfov_deg"), "must be in (0, 180) degrees");
    }
  }
  if (const std::string problem = camera_problem(camera); !problem.empty()) r.fail(path, problem);
  return camera;
}

/// Reads translate / rotate_deg_axis / quaternion / scale on top of `base` (fields not given
/// keep base's values).
Transform read_transform_fields(const Reader& r, const Json& j, const std::string& path,
                                Transform base) {
  if (const Json* v = r.optional(j, "translate"))
    base.translate = r.vec3(*v, child(path, "translate"));
  const Json* axis_angle = r.optional(j, "rotate_deg_axis");
  const Json* quaternion = r.optional(j, "quaternion");
  if (axis_angle != nullptr && quaternion != nullptr) {
    r.fail(path, "give rotate_deg_axis or quaternion, not both");
  }
  if (axis_angle != nullptr) {
    const std::string p = child(path, "rotate_deg_axis");
    r.array(*axis_angle, p, 4);
    const double degrees = r.number((*axis_angle)[0], element(p, 0));
    glm::dvec3 axis;
    for (int a = 0; a < 3; ++a) axis[a] = r.number((*axis_angle)[a + 1], element(p, a + 1));
    if (!(glm::length(axis) > 0.0)) r.fail(p, "rotation axis must not be zero");
    const glm::dquat q = rotation_deg_axis(degrees, glm::normalize(axis));
    base.rotate = glm::quat(static_cast<float>(q.w), static_cast<float>(q.x),
                            static_cast<float>(q.y), static_cast<float>(q.z));
  }
  if (quaternion != nullptr) {
    const std::string p = child(path, "quaternion");
    r.array(*quaternion, p, 4);
    glm::dquat q;
    q.w = r.number((*quaternion)[0], element(p, 0));
    q.x = r.number((*quaternion)[1], element(p, 1));
    q.y = r.number((*quaternion)[2], element(p, 2));
    q.z = r.number((*quaternion)[3], element(p, 3));
    if (!(glm::length(q) > 0.0)) r.fail(p, "quaternion must not be zero");
    q = glm::normalize(q);
    base.rotate = glm::quat(static_cast<float>(q.w), static_cast<float>(q.x),
                            static_cast<float>(q.y), static_cast<float>(q.z));
  }
  if (const Json* v = r.optional(j, "scale")) {
    const std::string p = child(path, "scale");
    base.scale = v->is_number() ? glm::vec3(r.real(*v, p)) : r.vec3(*v, p);
    if (base.scale.x == 0.0f || base.scale.y == 0.0f || base.scale.z == 0.0f) {
      r.fail(p, "scale must not be zero");
    }
    // The matrix entries are rotation (up to 1 + rounding) times scale, converted to float.
    if (max_abs(base.scale) > kMaxWorldCoordinate) {
      r.fail(p, fmt::format("scale must be within {:.3g}", kMaxWorldCoordinate));
    }
  }
  return base;
}

Material read_material(const Reader& r, const Json& j, const std::string& path) {
  r.expect_object(
      j, path, {"name", "diffuse", "specular", "shininess", "emission", "reflective", "opacity"});
  Material m;
  m.name = r.string(r.required(j, path, "name"), child(path, "name"));
  if (m.name.empty()) r.fail(child(path, "name"), "must not be empty");
  const auto color = [&](std::string_view key, glm::vec3& out) {
    if (const Json* v = r.optional(j, key)) out = r.color(*v, child(path, key));
  };
  color("diffuse", m.diffuse);
  color("specular", m.specular);
  color("emission", m.emission);
  if (const Json* v = r.optional(j, "shininess")) {
    m.shininess = r.real(*v, child(path, "shininess"));
    if (m.shininess < 0.0f) r.fail(child(path, "shininess"), "must not be negative");
  }
  if (const Json* v = r.optional(j, "reflective"))
    m.reflective = r.boolean(*v, child(path, "reflective"));
  if (const Json* v = r.optional(j, "opacity")) {
    m.opacity = r.real(*v, child(path, "opacity"));
    if (m.opacity < 0.0f || m.opacity > 1.0f) r.fail(child(path, "opacity"), "must be in [0, 1]");
  }
  return m;
}

template <typename Key>
void sort_keys(const Reader& r, std::vector<Key>& keys, const std::string& path) {
  std::stable_sort(keys.begin(), keys.end(),
                   [](const Key& a, const Key& b) { return a.frame < b.frame; });
  for (std::size_t i = 1; i < keys.size(); ++i) {
    if (keys[i].frame == keys[i - 1].frame) {
      r.fail(path, "two keys for frame " + std::to_string(keys[i].frame));
    }
  }
}

/// A frame number in [0, kMaxFrame]: output file names number frames from 0, and a pattern
/// such as frame_%04d.png has no way to write a negative one.
int frame_number(const Reader& r, const Json& j, const std::string& path) {
  const std::int64_t frame =
      r.integer(j, path, std::numeric_limits<std::int64_t>::min(), std::numeric_limits<std::int64_t>::max());
  if (frame < 0) {
    r.fail(path, "frame " + std::to_string(frame) +
                     " is negative (output file names number frames from 0)");
  }
  if (frame > kMaxFrame) {
    r.fail(path, "frame " + std::to_string(frame) + " is past the last a scene may have, " + std::to_string(kMaxFrame));
  }
  return static_cast<int>(frame);
}

class SceneJsonLoader {
 public:
  explicit SceneJsonLoader(const fs::path& path)
      : path_(path), folder_(path.parent_path()), r_(path.string()) {}

  Scene load() {
    const Json root = parse();
    r_.expect_object(root, "",
                     {"name", "mesh", "meshes", "triangles", "bounds", "camera", "lights",
                      "resolution", "source", "license", "notes", "materials", "background",
                      "ambient", "render", "animation"});
    scene_.source = path_;
    // Without a "name", the file's stem; a scene pack's view.json is named by its folder.
    scene_.name = path_.stem().string();
    if (scene_.name == "view") {
      const std::string folder = std::filesystem::absolute(path_).lexically_normal().parent_path().filename().string();
      if (!folder.empty()) scene_.name = folder;
    }
    scene_.materials.emplace_back();
    if (const Json* v = r_.optional(root, "name")) scene_.name = r_.string(*v, "name");
    for (const char* key : {"source", "license", "notes"}) {
      if (const Json* v = r_.optional(root, key)) (void)r_.string(*v, key);
    }
    if (const Json* v = r_.optional(root, "materials")) read_materials(*v);
    std::vector<MeshEntry> entries;
    if (const Json* v = r_.optional(root, "mesh")) {
      MeshEntry entry;
      entry.file = r_.string(*v, "mesh");
      entry.path = "mesh";
      entries.push_back(std::move(entry));
    }
    if (const Json* v = r_.optional(root, "meshes")) {
      r_.array(*v, "meshes");
      for (std::size_t i = 0; i < v->size(); ++i)
        entries.push_back(read_mesh_entry((*v)[i], element("meshes", i)));
    }
    for (MeshEntry& entry : entries) resolve(entry);
    for (const MeshEntry& entry : entries) ++uses_left_[entry.key];
    for (const MeshEntry& entry : entries) add_mesh(entry);
    if (scene_.meshes.empty()) {
      throw Error(r_.file() + ": no geometry (give \"mesh\" or \"meshes\")");
    }
    if (const Json* v = r_.optional(root, "triangles")) check_triangles(*v);
    if (const Json* v = r_.optional(root, "bounds")) {
      r_.array(*v, "bounds", 2);
      (void)r_.vec3((*v)[0], "bounds[0]");
      (void)r_.vec3((*v)[1], "bounds[1]");
    }
    if (const Json* v = r_.optional(root, "resolution")) {
      r_.array(*v, "resolution", 2);
      scene_.width = static_cast<int>(r_.integer((*v)[0], "resolution[0]", 1, 65536));
      scene_.height = static_cast<int>(r_.integer((*v)[1], "resolution[1]", 1, 65536));
    } else if (nff_resolution_) {
      scene_.width = nff_resolution_->x;
      scene_.height = nff_resolution_->y;
    }
    if (const Json* v = r_.optional(root, "background")) {
      scene_.background = r_.color(*v, "background");
    } else if (nff_background_) {
      scene_.background = *nff_background_;
    }
    if (const Json* v = r_.optional(root, "ambient")) scene_.ambient = r_.color(*v, "ambient");
    if (const Json* v = r_.optional(root, "render")) read_render(*v);

    const Json* lights = r_.optional(root, "lights");
    if (lights != nullptr) {
      read_lights(*lights);
    } else {
      scene_.lights = nff_lights_;
    }
    if (const Json* v = r_.optional(root, "camera")) {
      r_.expect_object(*v, "camera", {"eye", "look_at", "up", "vfov_deg"});
      (void)r_.required(*v, "camera", "eye");
      (void)r_.required(*v, "camera", "look_at");
      scene_.camera = read_camera_fields(r_, *v, "camera", Camera{});
    } else if (nff_camera_) {
      scene_.camera = *nff_camera_;
    } else {
      place_auto_camera(scene_);
    }
    if (lights == nullptr && scene_.lights.empty()) place_default_light(scene_);
    if (const Json* v = r_.optional(root, "animation")) read_animation(*v);

    spdlog::info("{}: {}, {}, {}, {}, frames {}..{}", path_.string(), counted(scene_.meshes.size(), "mesh", "meshes"),
                 counted(scene_.triangle_count(), "triangle", "triangles"),
                 counted(scene_.materials.size(), "material", "materials"),
                 counted(scene_.lights.size(), "light", "lights"), scene_.animation.frame_begin,
                 scene_.animation.frame_end);
    return std::move(scene_);
  }

 private:
  struct MeshEntry {
    std::string file;
    std::string path;  // JSON field path of the entry, for messages
    std::optional<std::string> name;
    Transform transform;
    std::optional<std::string> material;
    std::optional<Tessellation> tessellation;  // .nff only
    fs::path resolved;  // the file, relative to the JSON's folder
    std::string key;    // canonical path (and tessellation): one load per file
  };

  Json parse() const {
    const FileBytes bytes(path_);
    try {
      return Json::parse(bytes.view());
    } catch (const Json::exception& e) {  // parse_error, or out_of_range for 1e999
      std::string what = e.what();
      // Drop nlohmann's "[json.exception.parse_error.101] " prefix; keep line and column.
      const std::size_t bracket = what.find("] ");
      if (what.starts_with("[json.exception") && bracket != std::string::npos)
        what.erase(0, bracket + 2);
      throw Error(r_.file() + ": JSON " + what);
    }
  }

  void read_materials(const Json& list) {
    r_.array(list, "materials");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string path = element("materials", i);
      Material m = read_material(r_, list[i], path);
      if (m.name == "default" || inline_material_.contains(m.name)) {
        r_.fail(child(path, "name"), "material \"" + m.name + "\" defined twice (or \"default\")");
      }
      inline_material_[m.name] = static_cast<std::uint32_t>(scene_.materials.size());
      scene_.materials.push_back(std::move(m));
    }
  }

  MeshEntry read_mesh_entry(const Json& j, const std::string& path) const {
    r_.expect_object(j, path, {"file", "name", "transform", "material", "tessellation"});
    MeshEntry entry;
    entry.path = path;
    entry.file = r_.string(r_.required(j, path, "file"), child(path, "file"));
    if (const Json* v = r_.optional(j, "name")) entry.name = r_.string(*v, child(path, "name"));
    if (const Json* v = r_.optional(j, "transform")) {
      const std::string p = child(path, "transform");
      r_.expect_object(*v, p, {"translate", "rotate_deg_axis", "quaternion", "scale"});
      entry.transform = read_transform_fields(r_, *v, p, Transform{});
    }
    if (const Json* v = r_.optional(j, "material"))
      entry.material = r_.string(*v, child(path, "material"));
    if (const Json* v = r_.optional(j, "tessellation")) {
      const std::string p = child(path, "tessellation");
      r_.expect_object(*v, p, {"sphere", "cone"});
      Tessellation t;
      if (const Json* n = r_.optional(*v, "sphere")) {
        t.sphere_quads = static_cast<int>(r_.integer(*n, child(p, "sphere"),
                                                     Tessellation::kMinSphereQuads,
                                                     Tessellation::kMaxSphereQuads));
      }
      if (const Json* n = r_.optional(*v, "cone")) {
        t.cone_segments = static_cast<int>(r_.integer(*n, child(p, "cone"),
                                                      Tessellation::kMinConeSegments,
                                                      Tessellation::kMaxConeSegments));
      }
      entry.tessellation = t;
    }
    return entry;
  }

  static std::string file_field(const MeshEntry& entry) {
    return entry.path == "mesh" ? "mesh" : child(entry.path, "file");
  }

  static std::string transform_field(const MeshEntry& entry) {
    return entry.path == "mesh" ? "mesh" : child(entry.path, "transform");
  }

  /// Checks that the mesh file exists (before anything is loaded) and names it canonically.
  void resolve(MeshEntry& entry) const {
    if (entry.file.empty()) r_.fail(file_field(entry), "empty file name");
    // A NUL would end the name the system sees early: another file than the one written.
    if (entry.file.find('\0') != std::string::npos) r_.fail(file_field(entry), "file name contains a NUL byte");
    entry.resolved =
        fs::path(entry.file).is_absolute() ? fs::path(entry.file) : folder_ / entry.file;
    if (const std::string why = missing_file_reason(entry.resolved.string()); !why.empty()) {
      r_.fail(file_field(entry), "mesh file \"" + entry.file + "\" " +
                                     (why == kFileNotFound ? std::string("not found") : "cannot be used: " + why) +
                                     " (looked for " + entry.resolved.string() + ")");
    }
    std::error_code ec;
    entry.key = fs::weakly_canonical(entry.resolved, ec).string();
    if (ec) entry.key = entry.resolved.string();
    if (entry.tessellation) {
      std::string ext = entry.resolved.extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (ext != ".nff") {
        r_.fail(child(entry.path, "tessellation"),
                "only .nff meshes are tessellated (\"" + entry.file + "\" is not one)");
      }
      // Another tessellation of the same file is another mesh.
      if (*entry.tessellation != Tessellation{}) {
        entry.key += fmt::format("\ntessellation {} {}", entry.tessellation->sphere_quads,
                                 entry.tessellation->cone_segments);
      }
    }
  }

  void add_mesh(const MeshEntry& entry) {
    auto it = cache_.find(entry.key);
    if (it == cache_.end()) {
      try {
        MeshLoadOptions options;
        if (entry.tessellation) options.tessellation = *entry.tessellation;
        it = cache_.emplace(entry.key, load_mesh_file(entry.resolved, options)).first;
      } catch (const Error& e) {
        throw Error(std::string(e.what()) + " (loading field \"" + file_field(entry) + "\" of " +
                    r_.file() + ")");
      }
    }
    MeshFile& file = it->second;
    // The last entry using a file takes its mesh instead of copying it (2M triangles: ~30 ms).
    Mesh mesh = --uses_left_[entry.key] == 0 ? std::move(file.mesh) : file.mesh;
    mesh.name = entry.name ? *entry.name : entry.resolved.stem().string();
    mesh.world_from_object = entry.transform.matrix();
    input_triangles_ += mesh.triangles.size() + mesh.dropped_degenerate;
    std::uint32_t index = 0;
    if (entry.material) {
      const std::uint32_t id = material_by_name(*entry.material, child(entry.path, "material"));
      std::fill(mesh.material_ids.begin(), mesh.material_ids.end(), id);
      scene_.meshes.push_back(std::move(mesh));
      index = static_cast<std::uint32_t>(scene_.meshes.size() - 1);
    } else {
      index = append_mesh(scene_, std::move(mesh), file.materials);
    }
    transforms_.push_back(entry.transform);
    reach_.push_back(object_reach(scene_.meshes[index]));
    check_reach(entry.transform, index, transform_field(entry));
    // An NFF brings its own view; the first one is used where the JSON gives none, moved by
    // the mesh's transform.
    const glm::mat4& world = scene_.meshes[index].world_from_object;
    // Checked in double first: the float products below would overflow to infinity.
    const auto check_moved = [&](const glm::vec3& p, double w, const std::string& what) {
      if (!(max_abs(glm::dmat4(world) * glm::dvec4(glm::dvec3(p), w)) <= kMaxWorldCoordinate)) {
        r_.fail(transform_field(entry),
                fmt::format("moves the {} of \"{}\" beyond the float range (|coordinate| > {})",
                            what, entry.file, kMaxWorldCoordinate));
      }
    };
    if (file.camera && !nff_camera_) {
      check_moved(file.camera->eye, 1.0, "NFF camera");
      check_moved(file.camera->look_at, 1.0, "NFF camera");
      check_moved(file.camera->up, 0.0, "NFF camera");
      Camera camera = *file.camera;
      camera.eye = glm::vec3(world * glm::vec4(camera.eye, 1.0f));
      camera.look_at = glm::vec3(world * glm::vec4(camera.look_at, 1.0f));
      camera.up = glm::vec3(world * glm::vec4(camera.up, 0.0f));
      nff_camera_ = camera;
    }
    if (!file.lights.empty() && nff_lights_.empty()) {
      for (PointLight light : file.lights) {
        check_moved(light.position, 1.0, "NFF lights");
        light.position = glm::vec3(world * glm::vec4(light.position, 1.0f));
        nff_lights_.push_back(light);
      }
    }
    if (file.resolution && !nff_resolution_) nff_resolution_ = file.resolution;
    if (file.background && !nff_background_) nff_background_ = file.background;
  }

  /// Fails at `field` unless `transform` keeps scene mesh `index` within kMaxWorldCoordinate.
  void check_reach(const Transform& transform, std::uint32_t index,
                   const std::string& field) const {
    const double reach = world_reach(transform, reach_[index]);
    if (!(reach <= kMaxWorldCoordinate)) {
      r_.fail(field, fmt::format("translate and scale let mesh \"{}\" reach world coordinates "
                                 "of {:.3g} (for some rotation), beyond the float range (limit "
                                 "{:.3g})",
                                 scene_.meshes[index].name, reach, kMaxWorldCoordinate));
    }
  }

  std::uint32_t material_by_name(const std::string& name, const std::string& path) const {
    if (name == "default") return 0;
    const auto it = inline_material_.find(name);
    if (it != inline_material_.end()) return it->second;
    for (std::size_t i = 0; i < scene_.materials.size(); ++i) {
      if (scene_.materials[i].name == name) return static_cast<std::uint32_t>(i);
    }
    r_.fail(path, "no material named \"" + name + "\" (define it in \"materials\")");
  }

  void check_triangles(const Json& j) const {
    const std::int64_t expected =
        r_.integer(j, "triangles", 0, std::numeric_limits<std::int64_t>::max());
    if (static_cast<std::uint64_t>(expected) != input_triangles_) {
      spdlog::warn("{}: \"triangles\" says {}, the meshes have {} (before dropping degenerates)",
                   r_.file(), expected, input_triangles_);
    }
  }

  void read_render(const Json& j) {
    r_.expect_object(j, "render", {"max_depth", "min_weight", "spp", "intersector"});
    if (const Json* v = r_.optional(j, "max_depth")) {
      scene_.settings.max_depth = static_cast<int>(r_.integer(*v, "render.max_depth", 0, 64));
    }
    if (const Json* v = r_.optional(j, "min_weight")) {
      scene_.settings.min_weight = r_.real(*v, "render.min_weight");
      if (scene_.settings.min_weight < 0.0f || scene_.settings.min_weight > 1.0f) {
        r_.fail("render.min_weight", "must be in [0, 1]");
      }
    }
    if (const Json* v = r_.optional(j, "spp")) {
      scene_.settings.spp = static_cast<int>(r_.integer(*v, "render.spp", 1, 4096));
    }
    if (const Json* v = r_.optional(j, "intersector")) {
      const std::string name = r_.string(*v, "render.intersector");
      if (name == "wald") {
        scene_.settings.intersector = Intersector::Wald;
      } else if (name == "watertight") {
        scene_.settings.intersector = Intersector::Watertight;
      } else {
        r_.fail("render.intersector", "must be \"wald\" or \"watertight\", got \"" + name + "\"");
      }
    }
  }

  void read_lights(const Json& list) {
    r_.array(list, "lights");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string path = element("lights", i);
      r_.expect_object(list[i], path, {"position", "color"});
      PointLight light;
      light.position = r_.vec3(r_.required(list[i], path, "position"), child(path, "position"));
      if (const Json* v = r_.optional(list[i], "color"))
        light.color = r_.color(*v, child(path, "color"));
      scene_.lights.push_back(light);
    }
  }

  void read_animation(const Json& j) {
    r_.expect_object(j, "animation", {"frames", "camera", "meshes", "lights"});
    Animation& anim = scene_.animation;
    const Json& frames = r_.array(r_.required(j, "animation", "frames"), "animation.frames", 2);
    anim.frame_begin = frame_number(r_, frames[0], "animation.frames[0]");
    anim.frame_end = frame_number(r_, frames[1], "animation.frames[1]");
    if (anim.frame_end < anim.frame_begin)
      r_.fail("animation.frames", "end frame before begin frame");

    if (const Json* list = r_.optional(j, "camera")) {
      r_.array(*list, "animation.camera");
      for (std::size_t i = 0; i < list->size(); ++i) {
        const std::string path = element("animation.camera", i);
        const Json& key = (*list)[i];
        r_.expect_object(key, path, {"frame", "eye", "look_at", "up", "vfov_deg"});
        CameraKey ck;
        ck.frame = read_frame(key, path);
        ck.camera = read_camera_fields(r_, key, path, scene_.camera);
        anim.camera.push_back(ck);
      }
      sort_keys(r_, anim.camera, "animation.camera");
    }

    if (const Json* list = r_.optional(j, "meshes")) {
      anim.meshes = read_tracks<MeshTrack>(
          *list, "animation.meshes", "mesh", &MeshTrack::mesh,
          {"frame", "translate", "rotate_deg_axis", "quaternion", "scale"},
          [&](const Json& target, const std::string& path) { return mesh_ref(target, path); },
          [&](const Json& key, const std::string& key_path, std::uint32_t mesh) {
            TransformKey tk;
            tk.transform = read_transform_fields(r_, key, key_path, transforms_[mesh]);
            check_reach(tk.transform, mesh, key_path);
            return tk;
          });
    }

    if (const Json* list = r_.optional(j, "lights")) {
      anim.lights = read_tracks<LightTrack>(
          *list, "animation.lights", "light", &LightTrack::light, {"frame", "position"},
          [&](const Json& target, const std::string& path) {
            const auto max_light = static_cast<std::int64_t>(scene_.lights.size()) - 1;
            if (max_light < 0) r_.fail(path, "the scene has no lights");
            return static_cast<std::uint32_t>(r_.integer(target, path, 0, max_light));
          },
          [&](const Json& key, const std::string& key_path, std::uint32_t) {
            LightKey lk;
            lk.position =
                r_.vec3(r_.required(key, key_path, "position"), child(key_path, "position"));
            return lk;
          });
    }
  }

  /// Reads a list of tracks (animation.meshes, animation.lights): objects with a target field
  /// (`target_field`, stored in `Track::*target` by `read_target(json, path)`) and "keys", at
  /// most one track per target. Each key is an object with `key_fields`; its frame is read
  /// here, the rest by `read_key(json, path, target)`. Keys come back sorted, no frame twice.
  template <typename Track, typename ReadTarget, typename ReadKey>
  std::vector<Track> read_tracks(const Json& list, const std::string& list_path,
                                 std::string_view target_field, std::uint32_t Track::*target,
                                 std::initializer_list<std::string_view> key_fields,
                                 ReadTarget read_target, ReadKey read_key) const {
    r_.array(list, list_path);
    std::vector<Track> tracks;
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string path = element(list_path, i);
      const std::string target_path = child(path, target_field);
      r_.expect_object(list[i], path, {target_field, "keys"});
      Track track;
      track.*target = read_target(r_.required(list[i], path, target_field), target_path);
      for (const Track& other : tracks) {
        if (other.*target == track.*target) {
          r_.fail(target_path, std::string(target_field) + " already has a track");
        }
      }
      const std::string keys_path = child(path, "keys");
      const Json& keys = r_.array(r_.required(list[i], path, "keys"), keys_path);
      if (keys.empty()) r_.fail(keys_path, "a track needs at least one key");
      for (std::size_t k = 0; k < keys.size(); ++k) {
        const std::string key_path = element(keys_path, k);
        r_.expect_object(keys[k], key_path, key_fields);
        const int frame = read_frame(keys[k], key_path);
        auto key = read_key(keys[k], key_path, track.*target);
        key.frame = frame;
        track.keys.push_back(std::move(key));
      }
      sort_keys(r_, track.keys, keys_path);
      tracks.push_back(std::move(track));
    }
    return tracks;
  }

  int read_frame(const Json& key, const std::string& path) const {
    return frame_number(r_, r_.required(key, path, "frame"), child(path, "frame"));
  }

  std::uint32_t mesh_ref(const Json& j, const std::string& path) const {
    if (j.is_string()) {
      const std::string name = j.get<std::string>();
      std::optional<std::uint32_t> found;
      for (std::size_t i = 0; i < scene_.meshes.size(); ++i) {
        if (scene_.meshes[i].name != name) continue;
        if (found) r_.fail(path, "several meshes are named \"" + name + "\"; use the index");
        found = static_cast<std::uint32_t>(i);
      }
      if (!found) r_.fail(path, "no mesh named \"" + name + "\"");
      return *found;
    }
    return static_cast<std::uint32_t>(
        r_.integer(j, path, 0, static_cast<std::int64_t>(scene_.meshes.size()) - 1));
  }

  fs::path path_;
  fs::path folder_;
  Reader r_;
  Scene scene_;
  std::map<std::string, MeshFile> cache_;
  std::map<std::string, int> uses_left_;
  std::map<std::string, std::uint32_t> inline_material_;
  std::vector<Transform> transforms_;  // static transform of each scene mesh
  std::vector<glm::dvec3> reach_;      // per scene mesh: largest |object coordinate| per axis
  std::uint64_t input_triangles_ = 0;
  std::optional<Camera> nff_camera_;
  std::vector<PointLight> nff_lights_;
  std::optional<glm::ivec2> nff_resolution_;
  std::optional<glm::vec3> nff_background_;
};

}  // namespace

Scene load_scene_json(const std::filesystem::path& path) { return SceneJsonLoader(path).load(); }

}  // namespace rtc
