// glTF 2.0 (.gltf + .bin, .glb) loader: TinyGLTF parses the container (JSON, GLB chunks,
// data: URIs, external buffers); every byte of geometry is then read here, through accessors
// and buffer views whose ranges are checked against the buffers first. Node matrices and
// instancing are baked into one world-space mesh; materials come from baseColorFactor and
// emissiveFactor.
//
// Why not Assimp (used until the fuzz targets came): Debian 12's Assimp 5.2.5 reads past the end
// of a buffer for an accessor whose range exceeds its buffer view (tests/fuzz/regressions/gltf:
// a heap overflow found within seconds by fuzz_gltf) and leaks on other malformed files.
// TinyGLTF leaves the accessor arithmetic to its caller, which is where the checks belong. It
// is asked not to decode images (rtc uses no textures) and reads files only through
// FileBytes (regular files and pipes, never devices).
//
// Measured (dev container, Release, page cache, best of 9, scene_load_timing): 2CylinderEngine.glb
// (121,496 triangles after instancing, 110,336 after dropping degenerates) loads in 9.0-9.6 ms
// whole, against 8.1 ms for Assimp's ReadFile alone (the Assimp-based loader took 9.6 ms whole).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <tiny_gltf.h>

#include "common/base/error.h"
#include "common/base/log.h"
#include "common/scene/file_bytes.h"
#include "common/scene/material_values.h"
#include "common/scene/mesh_builder.h"
#include "common/scene/mesh_file.h"

namespace rtc {
namespace {

constexpr double kFloatMax = std::numeric_limits<float>::max();
constexpr int kComponentFloat = 5126;
constexpr int kComponentUnsignedByte = 5121;
constexpr int kComponentUnsignedShort = 5123;
constexpr int kComponentUnsignedInt = 5125;
constexpr int kModePoints = 0;
constexpr int kModeTriangles = 4;
constexpr int kModeTriangleStrip = 5;
constexpr int kModeTriangleFan = 6;
/// Instancing multiplies triangles without growing the file: a limit on what one file may
/// expand to (4x the kd-tree's 2^30 would not fit in memory anyway).
constexpr std::uint64_t kMaxTriangles = std::uint64_t{1} << 28;

/// The largest |component|; NaN when any component is NaN.
double max_abs(const glm::dvec3& v) {
  if (std::isnan(v.x) || std::isnan(v.y) || std::isnan(v.z)) return v.x + v.y + v.z;
  return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
}

// TinyGLTF's file access: FileBytes for reads, nothing written, paths as given. A folder is
// passed on to FileBytes, which names it as one (TinyGLTF's own message would be "File not
// found"); a device is never opened (a URI can name any path: opening a terminal or watchdog
// device can block or act), so it stays "not found".
bool file_exists(const std::string& path, void*) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  return std::filesystem::is_regular_file(st) || std::filesystem::is_fifo(st) || std::filesystem::is_directory(st);
}
std::string expand_path(const std::string& path, void*) { return path; }
bool read_whole_file(std::vector<unsigned char>* out, std::string* err, const std::string& path, void*) {
  try {
    const FileBytes bytes(path);
    const std::string_view view = bytes.view();
    out->assign(view.begin(), view.end());
    return true;
  } catch (const Error& e) {
    if (err != nullptr) *err += e.what();
    return false;
  }
}
bool write_whole_file(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err != nullptr) *err += "writing files is not allowed";
  return false;
}
// Images are not decoded: materials use colour factors only.
bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;
}

class GltfReader {
 public:
  /// Textures are never read (a texture file missing is no error either): a textured model is
  /// drawn with its materials' colour factors, which its author may not expect. Said once a file.
  void note_textures() const {
    std::size_t textured = 0;
    for (const tinygltf::Material& m : model_.materials) {
      if (m.pbrMetallicRoughness.baseColorTexture.index >= 0) ++textured;
    }
    if (textured > 0) {
      spdlog::info("{}: {} of {} materials have a base colour texture; rtc draws their colour factors only "
                   "(textures are not read)",
                   file_, textured, model_.materials.size());
    }
  }

  explicit GltfReader(const std::filesystem::path& path)
      : path_(path), file_(path.string()), builder_(path.stem().string(), path.string()) {}

  MeshFile read() {
    parse();
    // Material ids: identical materials (the engine repeats them) share one slot.
    material_of_.resize(model_.materials.size());
    for (std::size_t i = 0; i < model_.materials.size(); ++i) material_of_[i] = material_id(to_material(i));
    if (materials_.empty()) materials_.emplace_back();
    note_textures();
    for (const int root : roots()) visit(root, glm::dmat4(1.0), 0);
    MeshFile file;
    file.mesh = builder_.finish();
    file.materials = std::move(materials_);
    return file;
  }

 private:
  [[noreturn]] void fail(const std::string& message) const { throw_at(file_, 0, "glTF: " + message); }

  void parse() {
    const FileBytes bytes(path_);
    const std::string_view text = bytes.view();
    if (text.size() > std::numeric_limits<unsigned int>::max()) fail("file larger than 4 GiB");
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(skip_image, nullptr);
    loader.SetFsCallbacks(tinygltf::FsCallbacks{file_exists, expand_path, read_whole_file, write_whole_file, nullptr});
    std::string err, warn;
    const std::string base_dir = path_.parent_path().string();
    const auto length = static_cast<unsigned int>(text.size());
    const bool ok = text.substr(0, 4) == "glTF"
                        ? loader.LoadBinaryFromMemory(&model_, &err, &warn, reinterpret_cast<const unsigned char*>(text.data()),
                                                      length, base_dir)
                        : loader.LoadASCIIFromString(&model_, &err, &warn, text.data(), length, base_dir);
    if (!ok) fail(err.empty() ? std::string("not a glTF 2.0 file") : trimmed(err));
    check_version();
  }

  // glTF 2.0, section 3.2 (asset): a client must not load an asset whose major version it does
  // not support, nor one whose minVersion is above the version it supports (2.0 here). TinyGLTF
  // reads both strings without checking them.
  void check_version() const {
    const auto parsed = [](const std::string& v) -> std::optional<std::pair<int, int>> {
      const std::size_t dot = v.find('.');
      if (dot == std::string::npos || dot == 0 || dot + 1 == v.size() || dot > 4 || v.size() - dot > 5) return std::nullopt;
      for (std::size_t i = 0; i < v.size(); ++i) {
        if (i != dot && (v[i] < '0' || v[i] > '9')) return std::nullopt;
      }
      return std::pair{std::stoi(v.substr(0, dot)), std::stoi(v.substr(dot + 1))};
    };
    const std::string& version = model_.asset.version;
    const auto v = parsed(version);
    if (!v) fail("asset.version '" + version + "' is not of the form <major>.<minor>");
    if (v->first != 2) fail("version " + version + " is not supported (rtc reads glTF 2.x)");
    const std::string& min_version = model_.asset.minVersion;
    if (min_version.empty()) return;
    const auto m = parsed(min_version);
    if (!m) fail("asset.minVersion '" + min_version + "' is not of the form <major>.<minor>");
    if (*m > std::pair{2, 0}) fail("asset.minVersion " + min_version + " is above 2.0, the version rtc reads");
  }

  static std::string trimmed(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
    return s;
  }

  // The scene's root nodes (the default scene, else the first, else every node that is no
  // node's child), after checking that the nodes form a forest: each node at most one parent,
  // no root with a parent. Then visiting from the roots reaches each node once.
  std::vector<int> roots() {
    const std::size_t n = model_.nodes.size();
    std::vector<int> parent(n, -1);
    for (std::size_t i = 0; i < n; ++i) {
      for (const int c : model_.nodes[i].children) {
        if (c < 0 || static_cast<std::size_t>(c) >= n) fail(node_name(i) + " has a missing child " + std::to_string(c));
        if (static_cast<std::size_t>(c) == i) fail(node_name(c) + " is its own child");
        if (parent[c] >= 0) fail(node_name(c) + " has more than one parent");
        parent[c] = static_cast<int>(i);
      }
    }
    std::vector<int> out;
    if (!model_.scenes.empty()) {
      const int s = model_.defaultScene >= 0 ? model_.defaultScene : 0;
      if (static_cast<std::size_t>(s) >= model_.scenes.size()) fail("the default scene " + std::to_string(s) + " is missing");
      out = model_.scenes[s].nodes;
    } else {
      for (std::size_t i = 0; i < n; ++i) {
        if (parent[i] < 0) out.push_back(static_cast<int>(i));
      }
    }
    std::vector<bool> seen(n, false);
    for (const int r : out) {
      if (r < 0 || static_cast<std::size_t>(r) >= n) fail("the scene names a missing node " + std::to_string(r));
      if (parent[r] >= 0) fail(node_name(r) + " is a scene root and another node's child");
      if (seen[r]) fail(node_name(r) + " is listed twice in the scene");
      seen[r] = true;
    }
    // A cycle reachable from no root has no node without a parent: it is simply not visited.
    return out;
  }

  std::string node_name(std::size_t i) const {
    const std::string& name = model_.nodes[i].name;
    return "node " + std::to_string(i) + (name.empty() ? "" : " (\"" + name + "\")");
  }

  glm::dmat4 local_matrix(std::size_t i) const {
    const tinygltf::Node& node = model_.nodes[i];
    glm::dmat4 m(1.0);
    if (!node.matrix.empty()) {
      if (node.matrix.size() != 16) fail(node_name(i) + ": matrix must have 16 numbers");
      for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 4; ++r) m[c][r] = node.matrix[static_cast<std::size_t>(4 * c + r)];  // column-major
      }
      return m;
    }
    if (!node.translation.empty()) {
      if (node.translation.size() != 3) fail(node_name(i) + ": translation must have 3 numbers");
      m = glm::translate(m, glm::dvec3(node.translation[0], node.translation[1], node.translation[2]));
    }
    if (!node.rotation.empty()) {
      if (node.rotation.size() != 4) fail(node_name(i) + ": rotation must have 4 numbers");
      // glTF stores x, y, z, w; glm::dquat takes w first.
      glm::dquat q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
      // glTF requires a unit quaternion; mat4_cast of another one also scales and skews. A
      // rounded unit one is taken as it is; others are normalised, with a warning.
      const double length = glm::length(q);
      if (!(length > 0.0) || !std::isfinite(length)) fail(node_name(i) + ": rotation must be a non-zero, finite quaternion");
      if (std::abs(length - 1.0) > 1e-6) {
        if (std::abs(length - 1.0) > 1e-3) {
          spdlog::warn("{}: {}: rotation ({}, {}, {}, {}) is not a unit quaternion (length {:.6g}); normalised",
                       file_, node_name(i), node.rotation[0], node.rotation[1], node.rotation[2],
                       node.rotation[3], length);
        }
        q = q / length;
      }
      m = m * glm::mat4_cast(q);
    }
    if (!node.scale.empty()) {
      if (node.scale.size() != 3) fail(node_name(i) + ": scale must have 3 numbers");
      m = glm::scale(m, glm::dvec3(node.scale[0], node.scale[1], node.scale[2]));
    }
    return m;
  }

  void visit(int index, const glm::dmat4& parent, int depth) {
    if (depth > 256) fail("node hierarchy deeper than 256 levels");
    const auto i = static_cast<std::size_t>(index);
    const glm::dmat4 world = parent * local_matrix(i);
    const tinygltf::Node& node = model_.nodes[i];
    if (node.mesh >= 0) {
      if (static_cast<std::size_t>(node.mesh) >= model_.meshes.size()) fail(node_name(i) + " references a missing mesh");
      const tinygltf::Mesh& mesh = model_.meshes[static_cast<std::size_t>(node.mesh)];
      for (std::size_t p = 0; p < mesh.primitives.size(); ++p) add_primitive(mesh, p, world, i);
    }
    for (const int c : node.children) visit(c, world, depth + 1);
  }

  /// The bytes of `count` elements of accessor `index`, checked: element e of size `element`
  /// starts at data + e * stride.
  struct View {
    const unsigned char* data = nullptr;
    std::size_t count = 0, stride = 0;
  };
  /// Accessor `index`; fails naming `what` when the file has no such accessor.
  const tinygltf::Accessor& accessor(int index, const std::string& what) const {
    if (index < 0 || static_cast<std::size_t>(index) >= model_.accessors.size()) {
      fail(what + ": accessor " + std::to_string(index) + " is missing");
    }
    return model_.accessors[static_cast<std::size_t>(index)];
  }

  View accessor_view(int index, const std::string& what, std::size_t element) const {
    const tinygltf::Accessor& a = accessor(index, what);
    const std::string name = what + " (accessor " + std::to_string(index) + ")";
    if (a.sparse.isSparse) fail(name + ": sparse accessors are not supported");
    if (a.bufferView < 0 || static_cast<std::size_t>(a.bufferView) >= model_.bufferViews.size()) {
      fail(name + ": no buffer view (accessors of zeros are not supported)");
    }
    const tinygltf::BufferView& v = model_.bufferViews[static_cast<std::size_t>(a.bufferView)];
    if (v.buffer < 0 || static_cast<std::size_t>(v.buffer) >= model_.buffers.size()) fail(name + ": its buffer view has no buffer");
    const std::vector<unsigned char>& buffer = model_.buffers[static_cast<std::size_t>(v.buffer)].data;
    // In 64-bit unsigned arithmetic from values each below 2^53: no sum below overflows.
    const std::uint64_t view_end = std::uint64_t{v.byteOffset} + v.byteLength;
    if (v.byteOffset > buffer.size() || v.byteLength > buffer.size() || view_end > buffer.size()) {
      fail(name + ": buffer view " + std::to_string(a.bufferView) + " (bytes " + std::to_string(v.byteOffset) + " + " +
           std::to_string(v.byteLength) + ") exceeds its buffer of " + std::to_string(buffer.size()) + " bytes");
    }
    const std::size_t stride = v.byteStride == 0 ? element : v.byteStride;
    if (stride < element) fail(name + ": byte stride " + std::to_string(stride) + " is smaller than an element");
    View out;
    out.count = a.count;
    out.stride = stride;
    if (a.count > 0) {
      const std::uint64_t end = std::uint64_t{a.byteOffset} + (std::uint64_t{a.count} - 1) * stride + element;
      if (a.byteOffset > v.byteLength || a.count > v.byteLength || end > v.byteLength) {
        fail(name + ": " + std::to_string(a.count) + " elements from byte " + std::to_string(a.byteOffset) +
             " exceed buffer view " + std::to_string(a.bufferView) + " of " + std::to_string(v.byteLength) + " bytes");
      }
      out.data = buffer.data() + v.byteOffset + a.byteOffset;
    }
    return out;
  }

  View vec3_floats(int index, const std::string& what) const {
    const View v = accessor_view(index, what, 12);
    const tinygltf::Accessor& a = accessor(index, what);
    if (a.componentType != kComponentFloat || a.type != TINYGLTF_TYPE_VEC3) {
      fail(what + " (accessor " + std::to_string(index) + "): must be float VEC3 (componentType " +
           std::to_string(a.componentType) + ", type " + std::to_string(a.type) + ")");
    }
    return v;
  }

  static glm::vec3 vec3_at(const View& v, std::size_t e) {
    float xyz[3];
    std::memcpy(xyz, v.data + e * v.stride, sizeof xyz);  // glTF is little-endian, as is x86-64
    return {xyz[0], xyz[1], xyz[2]};
  }

  std::vector<std::uint32_t> indices(int index, const std::string& what, std::size_t vertices) const {
    if (index < 0) {  // no indices: the vertices in order
      std::vector<std::uint32_t> out(vertices);
      for (std::size_t k = 0; k < vertices; ++k) out[k] = static_cast<std::uint32_t>(k);
      return out;
    }
    const tinygltf::Accessor& a = accessor(index, what);
    const std::size_t size = a.componentType == kComponentUnsignedByte    ? 1
                             : a.componentType == kComponentUnsignedShort ? 2
                             : a.componentType == kComponentUnsignedInt   ? 4
                                                                          : 0;
    if (a.type != TINYGLTF_TYPE_SCALAR || size == 0) {
      fail(what + " (accessor " + std::to_string(index) + "): must be SCALAR unsigned byte, short or int (componentType " +
           std::to_string(a.componentType) + ", type " + std::to_string(a.type) + ")");
    }
    const View v = accessor_view(index, what, size);
    std::vector<std::uint32_t> out(v.count);
    for (std::size_t k = 0; k < v.count; ++k) {
      const unsigned char* p = v.data + k * v.stride;
      std::uint32_t value = 0;
      if (size == 1) {
        value = *p;
      } else if (size == 2) {
        std::uint16_t s = 0;
        std::memcpy(&s, p, 2);
        value = s;
      } else {
        std::memcpy(&value, p, 4);
      }
      if (value >= vertices) {
        fail(what + ": index " + std::to_string(k) + " is " + std::to_string(value) + ", out of range (" +
             std::to_string(vertices) + " vertices)");
      }
      out[k] = value;
    }
    return out;
  }

  void add_primitive(const tinygltf::Mesh& mesh, std::size_t p, const glm::dmat4& world, std::size_t node) {
    const tinygltf::Primitive& prim = mesh.primitives[p];
    const std::string what = "mesh \"" + mesh.name + "\" primitive " + std::to_string(p) + " in " + node_name(node);
    if (prim.mode >= kModePoints && prim.mode < kModeTriangles) return;  // points and lines are not surfaces
    if (prim.mode != kModeTriangles && prim.mode != kModeTriangleStrip && prim.mode != kModeTriangleFan) {
      fail(what + ": unknown mode " + std::to_string(prim.mode));
    }
    const auto position_it = prim.attributes.find("POSITION");
    if (position_it == prim.attributes.end()) fail(what + ": no POSITION attribute");
    const View positions = vec3_floats(position_it->second, what + " POSITION");
    const auto normal_it = prim.attributes.find("NORMAL");
    View normals;
    if (normal_it != prim.attributes.end()) {
      normals = vec3_floats(normal_it->second, what + " NORMAL");
      if (normals.count != positions.count) fail(what + ": NORMAL and POSITION have different counts");
    }
    const std::vector<std::uint32_t> index = indices(prim.indices, what + " indices", positions.count);
    const std::size_t corners = index.size();
    const std::size_t triangles = prim.mode == kModeTriangles ? corners / 3 : (corners >= 3 ? corners - 2 : 0);
    triangles_ += triangles;
    if (triangles_ > kMaxTriangles) {
      fail("more than " + std::to_string(kMaxTriangles) + " triangles once instanced");
    }

    const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(glm::dmat3(world)));
    const std::uint32_t first = builder_.vertex_count();
    builder_.reserve(positions.count, triangles);
    for (std::size_t v = 0; v < positions.count; ++v) {
      const glm::vec3 p_object = vec3_at(positions, v);
      const glm::dvec3 world_position(world * glm::dvec4(glm::dvec3(p_object), 1.0));
      // Checked in double: converting a value beyond FLT_MAX to float is undefined.
      if (!(max_abs(world_position) <= kFloatMax)) {
        fail(what + ": vertex " + std::to_string(v) + " has a non-finite position or one outside the float range");
      }
      const glm::vec3 position(world_position);
      if (normals.data == nullptr) {
        builder_.add_vertex(position);
        continue;
      }
      glm::dvec3 world_normal = normal_matrix * glm::dvec3(vec3_at(normals, v));
      const double largest = max_abs(world_normal);
      if (!(largest <= kFloatMax)) {
        // Only the direction matters (the builder normalises): scale it into float range.
        world_normal = std::isfinite(largest) ? world_normal / largest : glm::dvec3(0.0);
      }
      builder_.add_vertex(position, glm::vec3(world_normal));
    }
    std::uint32_t material = default_material();
    if (prim.material >= 0) {
      if (static_cast<std::size_t>(prim.material) >= material_of_.size()) {
        fail(what + ": material " + std::to_string(prim.material) + " is missing");
      }
      material = material_of_[static_cast<std::size_t>(prim.material)];
    }
    builder_.set_material(material);
    // glTF 2.0 section 3.7.2.1: strips alternate winding, fans turn around vertex 0.
    for (std::size_t t = 0; t < triangles; ++t) {
      std::uint32_t a = 0, b = 0, c = 0;
      if (prim.mode == kModeTriangles) {
        a = index[3 * t], b = index[3 * t + 1], c = index[3 * t + 2];
      } else if (prim.mode == kModeTriangleStrip) {
        a = index[t], b = index[t + 1 + t % 2], c = index[t + 2 - t % 2];
      } else {
        a = index[t + 1], b = index[t + 2], c = index[0];
      }
      builder_.add_triangle(first + a, first + b, first + c);
    }
  }

  Material to_material(std::size_t i) const {
    const tinygltf::Material& source = model_.materials[i];
    Material m;
    if (!source.name.empty()) m.name = source.name;
    const std::string what = "material \"" + m.name + "\"";
    const std::vector<double>& base = source.pbrMetallicRoughness.baseColorFactor;
    if (base.size() != 4) fail(what + ": baseColorFactor must have 4 numbers");
    const std::vector<double>& emissive = source.emissiveFactor;
    if (emissive.size() != 3) fail(what + ": emissiveFactor must have 3 numbers");
    const auto to_float = [&](double v, const char* field) {
      if (!(std::abs(v) <= kFloatMax)) fail(what + ": " + field + " is not a finite float");
      return static_cast<float>(v);
    };
    m.diffuse = checked_color(glm::vec3(to_float(base[0], "baseColorFactor"), to_float(base[1], "baseColorFactor"),
                                        to_float(base[2], "baseColorFactor")),
                              what + " base colour", file_, 0);
    m.opacity = checked_opacity(to_float(base[3], "baseColorFactor alpha"), what + " baseColorFactor alpha", file_, 0);
    m.emission = checked_color(glm::vec3(to_float(emissive[0], "emissiveFactor"), to_float(emissive[1], "emissiveFactor"),
                                         to_float(emissive[2], "emissiveFactor")),
                               what + " emissive colour", file_, 0);
    return m;
  }

  std::uint32_t material_id(const Material& m) {
    std::uint32_t id = 0;
    while (id < materials_.size() && !(materials_[id] == m)) ++id;
    if (id == materials_.size()) materials_.push_back(m);
    return id;
  }

  // Primitives without a material get rtc's default material.
  std::uint32_t default_material() {
    if (!default_material_) default_material_ = material_id(Material{});
    return *default_material_;
  }

  std::filesystem::path path_;
  std::string file_;
  tinygltf::Model model_;
  MeshBuilder builder_;
  std::vector<Material> materials_;
  std::vector<std::uint32_t> material_of_;
  std::optional<std::uint32_t> default_material_;
  std::uint64_t triangles_ = 0;
};

}  // namespace

MeshFile load_gltf(const std::filesystem::path& path) { return GltfReader(path).read(); }

}  // namespace rtc
