// Scene bytes: the scene the master sends to every worker, carried field by field with the
// exact float bits so that a worker renders the same pixels as the master's own copy would.
#include "common/scene/serialize.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <fmt/format.h>

#include "common/base/byte_io.h"
#include "common/base/error.h"

namespace rtc {
namespace {

constexpr std::array<std::uint8_t, 4> kMagic = {'R', 'T', 'C', 'S'};
constexpr std::uint32_t kFormatVersion = 2;
// Image sides a worker accepts (32768 x 32768 RGBA float is already 16 GiB).
constexpr int kMaxImageSide = 32768;

/// Section tags: four ASCII bytes, compared as one little-endian u32.
constexpr std::uint32_t section_tag(std::string_view four) {
  return static_cast<std::uint32_t>(four[0]) | static_cast<std::uint32_t>(four[1]) << 8 |
         static_cast<std::uint32_t>(four[2]) << 16 | static_cast<std::uint32_t>(four[3]) << 24;
}
constexpr std::uint32_t kSceneTag = section_tag("SCEN");
constexpr std::uint32_t kMaterialsTag = section_tag("MATL");
constexpr std::uint32_t kLightsTag = section_tag("LGHT");
constexpr std::uint32_t kMeshesTag = section_tag("MESH");
constexpr std::uint32_t kAnimationTag = section_tag("ANIM");

// Bulk arrays travel as their in-memory bytes: these types must be packed floats / u32s.
static_assert(sizeof(glm::vec3) == 12 && std::is_trivially_copyable_v<glm::vec3>);
static_assert(sizeof(glm::uvec3) == 12 && std::is_trivially_copyable_v<glm::uvec3>);
static_assert(sizeof(glm::mat4) == 64 && std::is_trivially_copyable_v<glm::mat4>);

// The smallest encoding of each repeated record, to reject a count before allocating for it.
constexpr std::size_t kVec3Bytes = 12;
constexpr std::size_t kCameraBytes = 3 * kVec3Bytes + 4;
constexpr std::size_t kMaterialMinBytes = 4 + 3 * kVec3Bytes + 4 + 1 + 4;  // empty name
constexpr std::size_t kLightBytes = 2 * kVec3Bytes;
constexpr std::size_t kMeshMinBytes = 4 + 4 + 8 + 64 + 5 * 4;  // empty names and arrays
constexpr std::size_t kCameraKeyBytes = 4 + kCameraBytes;
constexpr std::size_t kTransformKeyBytes = 4 + kVec3Bytes + 16 + kVec3Bytes;
constexpr std::size_t kLightKeyBytes = 4 + kVec3Bytes;
constexpr std::size_t kTrackHeadBytes = 4 + 4;  // target index and key count

std::uint32_t count32(std::size_t n) {
  RTC_CHECK(n <= std::numeric_limits<std::uint32_t>::max(),
            "scene array too long for the u32 count of the scene bytes");
  return static_cast<std::uint32_t>(n);
}

void put_str(ByteWriter& w, std::string_view s) {
  (void)count32(s.size());
  w.str(s);
}

void put_vec3(ByteWriter& w, const glm::vec3& v) {
  w.f32(v.x);
  w.f32(v.y);
  w.f32(v.z);
}

void put_camera(ByteWriter& w, const Camera& c) {
  put_vec3(w, c.eye);
  put_vec3(w, c.look_at);
  put_vec3(w, c.up);
  w.f32(c.vfov_deg);
}

/// u32 count, then the elements' bytes as they are in memory.
template <typename T>
void put_array(ByteWriter& w, const std::vector<T>& v) {
  w.u32(count32(v.size()));
  w.raw(v.data(), v.size() * sizeof(T));
}

std::size_t encoded_size_estimate(const Scene& scene) {
  std::size_t n =
      1024 + scene.materials.size() * (kMaterialMinBytes + 16) + scene.lights.size() * kLightBytes;
  for (const Mesh& m : scene.meshes) {
    n += kMeshMinBytes + m.name.size() + m.source.size() +
         (m.positions.size() + m.normals.size()) * kVec3Bytes + m.triangles.size() * (12 + 4 + 4);
  }
  return n;
}

/// Reads the scene bytes and checks every value as it goes; the first problem throws
/// rtc::Error("<what>: <field> at byte <offset>: <reason>").
class SceneDecoder {
 public:
  SceneDecoder(std::span<const std::uint8_t> bytes, const std::string& what)
      : r_(bytes), what_(what) {}

  Scene decode() {
    Scene scene;
    header();
    section(kSceneTag, "SCEN");
    scene.name = str("name");
    scene.source = str("source");
    scene.width = image_side("width");
    scene.height = image_side("height");
    scene.background = vec3("background");
    scene.ambient = vec3("ambient");
    scene.settings = settings();
    scene.camera_automatic = boolean("camera_automatic");
    scene.camera = camera("camera");

    section(kMaterialsTag, "MATL");
    const std::size_t materials_at = r_.position();
    const std::uint32_t material_count = count("materials", kMaterialMinBytes);
    if (material_count == 0) {
      fail_at(materials_at, "materials", "no materials (material 0 is the default)");
    }
    scene.materials.resize(material_count);
    for (std::uint32_t i = 0; i < material_count; ++i) {
      scene.materials[i] = material(fmt::format("materials[{}]", i));
    }

    section(kLightsTag, "LGHT");
    scene.lights.resize(count("lights", kLightBytes));
    for (std::size_t i = 0; i < scene.lights.size(); ++i) {
      const std::string field = fmt::format("lights[{}]", i);
      scene.lights[i].position = vec3(field + ".position");
      scene.lights[i].color = vec3(field + ".color");
    }

    section(kMeshesTag, "MESH");
    scene.meshes.resize(count("meshes", kMeshMinBytes));
    for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
      scene.meshes[i] = mesh(fmt::format("meshes[{}]", i), material_count);
    }

    section(kAnimationTag, "ANIM");
    animation(scene);

    r_.finish("end of scene bytes");
    check();
    return scene;
  }

 private:
  void check() {
    if (!r_.ok()) throw Error(what_ + ": " + r_.error());
  }

  [[noreturn]] void fail_at(std::size_t at, std::string_view field, std::string_view reason) {
    throw Error(fmt::format("{}: {} at byte {}: {}", what_, field, at, reason));
  }

  void header() {
    const std::span<const std::uint8_t> magic = r_.take(kMagic.size(), "magic");
    check();
    if (!std::equal(magic.begin(), magic.end(), kMagic.begin())) {
      fail_at(0, "magic", "not scene bytes (expected \"RTCS\")");
    }
    const std::uint32_t version = r_.u32("format version");
    check();
    if (version != kFormatVersion) {
      fail_at(kMagic.size(), "format version",
              fmt::format("unsupported format version {} (this build reads {})", version,
                          kFormatVersion));
    }
  }

  void section(std::uint32_t tag, std::string_view name) {
    const std::size_t at = r_.position();
    const std::uint32_t found = r_.u32("section tag");
    check();
    if (found != tag) fail_at(at, "section tag", fmt::format("expected section \"{}\"", name));
  }

  std::string str(const std::string& field) {
    std::string s = r_.str(std::numeric_limits<std::uint32_t>::max(), field.c_str());
    check();
    return s;
  }

  std::int32_t i32(const std::string& field, std::size_t& at) {
    at = r_.position();
    const std::int32_t v = r_.i32(field.c_str());
    check();
    return v;
  }

  std::uint32_t u32(const std::string& field, std::size_t& at) {
    at = r_.position();
    const std::uint32_t v = r_.u32(field.c_str());
    check();
    return v;
  }

  bool boolean(const std::string& field) {
    const std::size_t at = r_.position();
    const std::uint8_t v = r_.u8(field.c_str());
    check();
    if (v > 1) fail_at(at, field, fmt::format("expected 0 or 1, got {}", v));
    return v == 1;
  }

  float real(const std::string& field) {
    const std::size_t at = r_.position();
    const float v = r_.f32(field.c_str());
    check();
    if (!std::isfinite(v)) fail_at(at, field, fmt::format("{} is not finite", v));
    return v;
  }

  glm::vec3 vec3(const std::string& field) {
    const std::size_t at = r_.position();
    glm::vec3 v;
    for (int a = 0; a < 3; ++a) v[a] = r_.f32(field.c_str());
    check();
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) {
      fail_at(at, field, fmt::format("({}, {}, {}) is not finite", v.x, v.y, v.z));
    }
    return v;
  }

  /// A u32 count of records of at least `min_bytes_each`, checked against the bytes left.
  std::uint32_t count(const std::string& field, std::size_t min_bytes_each) {
    std::size_t at = 0;
    const std::uint32_t n = u32(field + " count", at);
    if (n > r_.remaining() / min_bytes_each) {
      fail_at(at, field + " count",
              fmt::format("count {} needs at least {} bytes, {} left", n,
                          std::uint64_t{n} * min_bytes_each, r_.remaining()));
    }
    return n;
  }

  /// A counted array of T as raw bytes; `at` gets the offset of its first element.
  template <typename T>
  std::vector<T> array(const std::string& field, std::size_t& at) {
    const std::uint32_t n = count(field, sizeof(T));
    at = r_.position();
    const std::span<const std::uint8_t> bytes = r_.take(std::size_t{n} * sizeof(T), field.c_str());
    check();
    std::vector<T> v(n);
    if (n > 0) std::memcpy(v.data(), bytes.data(), bytes.size());
    return v;
  }

  /// Every component of `v[i]` (starting at byte `at`) finite.
  void check_finite(const std::vector<glm::vec3>& v, std::size_t at, const std::string& field) {
    for (std::size_t i = 0; i < v.size(); ++i) {
      const glm::vec3& p = v[i];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
        fail_at(at + i * kVec3Bytes, fmt::format("{}[{}]", field, i),
                fmt::format("({}, {}, {}) is not finite", p.x, p.y, p.z));
      }
    }
  }

  int image_side(const std::string& field) {
    std::size_t at = 0;
    const std::int32_t v = i32(field, at);
    if (v < 1 || v > kMaxImageSide) {
      fail_at(at, field, fmt::format("must be in [1, {}], got {}", kMaxImageSide, v));
    }
    return v;
  }

  int frame(const std::string& field) {
    std::size_t at = 0;
    const std::int32_t v = i32(field, at);
    if (v < 0 || v > kMaxFrame) {
      fail_at(at, field, fmt::format("frame must be in [0, {}], got {}", kMaxFrame, v));
    }
    return v;
  }

  RenderSettings settings() {
    const std::size_t at = r_.position();
    RenderSettings s;
    s.max_depth = r_.i32("settings.max_depth");
    s.min_weight = r_.f32("settings.min_weight");
    s.spp = r_.i32("settings.spp");
    s.intersector = static_cast<Intersector>(r_.u8("settings.intersector"));
    check();
    try {
      check_render_settings(s);
    } catch (const Error& e) {
      fail_at(at, "settings", e.what());
    }
    return s;
  }

  Camera camera(const std::string& field) {
    Camera c;
    c.eye = vec3(field + ".eye");
    c.look_at = vec3(field + ".look_at");
    c.up = vec3(field + ".up");
    c.vfov_deg = real(field + ".vfov_deg");
    return c;
  }

  Material material(const std::string& field) {
    Material m;
    m.name = str(field + ".name");
    m.diffuse = vec3(field + ".diffuse");
    m.specular = vec3(field + ".specular");
    m.shininess = real(field + ".shininess");
    m.emission = vec3(field + ".emission");
    m.reflective = boolean(field + ".reflective");
    m.opacity = real(field + ".opacity");
    return m;
  }

  Mesh mesh(const std::string& field, std::uint32_t material_count) {
    Mesh m;
    m.name = str(field + ".name");
    m.source = str(field + ".source");
    m.dropped_degenerate = r_.u64((field + ".dropped_degenerate").c_str());
    const std::size_t matrix_at = r_.position();
    const std::span<const std::uint8_t> matrix =
        r_.take(sizeof(glm::mat4), (field + ".world_from_object").c_str());
    check();
    std::memcpy(&m.world_from_object, matrix.data(), sizeof(glm::mat4));
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 4; ++r) {
        if (!std::isfinite(m.world_from_object[c][r])) {
          fail_at(
              matrix_at, field + ".world_from_object",
              fmt::format("column {} row {} is {}, not finite", c, r, m.world_from_object[c][r]));
        }
      }
    }

    std::size_t at = 0;
    m.positions = array<glm::vec3>(field + ".positions", at);
    check_finite(m.positions, at, field + ".positions");

    const std::size_t normals_count_at = r_.position();
    m.normals = array<glm::vec3>(field + ".normals", at);
    if (!m.normals.empty() && m.normals.size() != m.positions.size()) {
      fail_at(normals_count_at, field + ".normals count",
              fmt::format("{} normals for {} positions (give none or one per position)",
                          m.normals.size(), m.positions.size()));
    }
    check_finite(m.normals, at, field + ".normals");

    m.triangles = array<glm::uvec3>(field + ".triangles", at);
    const std::size_t vertex_count = m.positions.size();
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      const glm::uvec3& tri = m.triangles[t];
      if (tri.x >= vertex_count || tri.y >= vertex_count || tri.z >= vertex_count) {
        fail_at(at + t * sizeof(glm::uvec3), fmt::format("{}.triangles[{}]", field, t),
                fmt::format("indices ({}, {}, {}) reach beyond the {} positions", tri.x, tri.y,
                            tri.z, vertex_count));
      }
    }

    m.material_ids = per_triangle(field + ".material_ids", m.triangles.size(), at);
    for (std::size_t t = 0; t < m.material_ids.size(); ++t) {
      if (m.material_ids[t] >= material_count) {
        fail_at(at + t * 4, fmt::format("{}.material_ids[{}]", field, t),
                fmt::format("material {} of {} materials", m.material_ids[t], material_count));
      }
    }
    m.source_index = per_triangle(field + ".source_index", m.triangles.size(), at);
    return m;
  }

  std::vector<std::uint32_t> per_triangle(const std::string& field, std::size_t triangle_count,
                                          std::size_t& at) {
    const std::size_t count_at = r_.position();
    std::vector<std::uint32_t> v = array<std::uint32_t>(field, at);
    if (v.size() != triangle_count) {
      fail_at(count_at, field + " count",
              fmt::format("{} entries for {} triangles (need one per triangle)", v.size(),
                          triangle_count));
    }
    return v;
  }

  /// A track's keys: at least one, frames strictly increasing (what pose_at assumes).
  template <typename Key, typename ReadKey>
  std::vector<Key> read_keys(const std::string& field, std::size_t key_bytes, bool at_least_one,
                             ReadKey read_key) {
    const std::size_t count_at = r_.position();
    std::vector<Key> keys(count(field, key_bytes));
    if (at_least_one && keys.empty()) {
      fail_at(count_at, field + " count", "a track needs at least one key");
    }
    for (std::size_t k = 0; k < keys.size(); ++k) {
      const std::string key_field = fmt::format("{}[{}]", field, k);
      const std::size_t at = r_.position();
      keys[k].frame = frame(key_field + ".frame");
      if (k > 0 && keys[k].frame <= keys[k - 1].frame) {
        fail_at(at, key_field + ".frame",
                fmt::format("frame {} after frame {}: keys must be sorted, no frame twice",
                            keys[k].frame, keys[k - 1].frame));
      }
      read_key(keys[k], key_field);
    }
    return keys;
  }

  /// A track's target index: one of has_track.size() meshes or lights, without a track yet.
  std::uint32_t track_target(const std::string& field, std::vector<bool>& has_track,
                             std::string_view kind) {
    std::size_t at = 0;
    const std::uint32_t target = u32(field, at);
    if (target >= has_track.size()) {
      fail_at(at, field,
              fmt::format("{} index {} out of range ({} in the scene)", kind, target,
                          has_track.size()));
    }
    if (has_track[target]) {
      fail_at(at, field, fmt::format("{} {} already has a track", kind, target));
    }
    has_track[target] = true;
    return target;
  }

  void animation(Scene& scene) {
    Animation& anim = scene.animation;
    anim.frame_begin = frame("animation.frame_begin");
    const std::size_t end_at = r_.position();
    anim.frame_end = frame("animation.frame_end");
    if (anim.frame_end < anim.frame_begin) {
      fail_at(end_at, "animation.frame_end",
              fmt::format("end frame {} before begin frame {}", anim.frame_end, anim.frame_begin));
    }
    anim.camera =
        read_keys<CameraKey>("animation.camera", kCameraKeyBytes, false,
                             [&](CameraKey& key, const std::string& f) { key.camera = camera(f); });

    std::vector<bool> mesh_has_track(scene.meshes.size(), false);
    anim.meshes.resize(count("animation.meshes", kTrackHeadBytes + kTransformKeyBytes));
    for (std::size_t i = 0; i < anim.meshes.size(); ++i) {
      const std::string field = fmt::format("animation.meshes[{}]", i);
      MeshTrack& track = anim.meshes[i];
      track.mesh = track_target(field + ".mesh", mesh_has_track, "mesh");
      track.keys = read_keys<TransformKey>(field + ".keys", kTransformKeyBytes, true,
                                           [&](TransformKey& key, const std::string& f) {
                                             key.transform.translate = vec3(f + ".translate");
                                             key.transform.rotate.w = real(f + ".rotate.w");
                                             key.transform.rotate.x = real(f + ".rotate.x");
                                             key.transform.rotate.y = real(f + ".rotate.y");
                                             key.transform.rotate.z = real(f + ".rotate.z");
                                             key.transform.scale = vec3(f + ".scale");
                                           });
    }

    std::vector<bool> light_has_track(scene.lights.size(), false);
    anim.lights.resize(count("animation.lights", kTrackHeadBytes + kLightKeyBytes));
    for (std::size_t i = 0; i < anim.lights.size(); ++i) {
      const std::string field = fmt::format("animation.lights[{}]", i);
      LightTrack& track = anim.lights[i];
      track.light = track_target(field + ".light", light_has_track, "light");
      track.keys = read_keys<LightKey>(
          field + ".keys", kLightKeyBytes, true,
          [&](LightKey& key, const std::string& f) { key.position = vec3(f + ".position"); });
    }
  }

  ByteReader r_;
  const std::string& what_;
};

}  // namespace

// The scene bytes, version 2 (all little-endian; f32 is the IEEE float's bits, vec3 is three
// f32 x, y, z; str is a u32 byte length then the bytes, no terminator; bool is a u8 0 or 1):
//   "RTCS" magic, u32 format version = 2 (version 1 lacked intersector)
//   "SCEN" name str, source str, width i32, height i32 (both in [1, 32768]), background vec3,
//          ambient vec3, max_depth i32 [0, 64], min_weight f32 [0, 1], spp i32 [1, 4096],
//          intersector u8 (0 wald, 1 watertight), camera_automatic bool, camera (eye vec3, look_at vec3, up vec3, vfov_deg f32)
//   "MATL" u32 count (>= 1), each: name str, diffuse vec3, specular vec3, shininess f32,
//          emission vec3, reflective bool, opacity f32
//   "LGHT" u32 count, each: position vec3, color vec3
//   "MESH" u32 count, each: name str, source str, dropped_degenerate u64, world_from_object
//          16 f32 (column-major, glm's order), then five counted arrays (u32 count, then the
//          elements): positions (vec3), normals (vec3; none or one per position), triangles
//          (3 u32 indices < position count), material_ids (u32 < material count, one per
//          triangle), source_index (u32, one per triangle)
//   "ANIM" frame_begin i32, frame_end i32 (0 <= begin <= end <= 1e9), u32 camera key count,
//          each: frame i32, camera; u32 mesh track count, each: mesh u32, u32 key count (>= 1),
//          each: frame i32, translate vec3, rotate f32 w x y z, scale vec3; u32 light track
//          count, each: light u32, u32 key count (>= 1), each: frame i32, position vec3.
//          Key frames are in [0, 1e9] and strictly increasing; at most one track per target.
// Nothing follows. Every f32 is finite. Section tags are their four ASCII bytes.
std::vector<std::uint8_t> serialize_scene(const Scene& scene) {
  std::vector<std::uint8_t> out;
  out.reserve(encoded_size_estimate(scene));
  ByteWriter w(out);
  w.raw(kMagic.data(), kMagic.size());
  w.u32(kFormatVersion);

  w.u32(kSceneTag);
  put_str(w, scene.name);
  put_str(w, scene.source.string());
  w.i32(scene.width);
  w.i32(scene.height);
  put_vec3(w, scene.background);
  put_vec3(w, scene.ambient);
  w.i32(scene.settings.max_depth);
  w.f32(scene.settings.min_weight);
  w.i32(scene.settings.spp);
  w.u8(static_cast<std::uint8_t>(scene.settings.intersector));
  w.u8(scene.camera_automatic ? 1 : 0);
  put_camera(w, scene.camera);

  w.u32(kMaterialsTag);
  w.u32(count32(scene.materials.size()));
  for (const Material& m : scene.materials) {
    put_str(w, m.name);
    put_vec3(w, m.diffuse);
    put_vec3(w, m.specular);
    w.f32(m.shininess);
    put_vec3(w, m.emission);
    w.u8(m.reflective ? 1 : 0);
    w.f32(m.opacity);
  }

  w.u32(kLightsTag);
  w.u32(count32(scene.lights.size()));
  for (const PointLight& light : scene.lights) {
    put_vec3(w, light.position);
    put_vec3(w, light.color);
  }

  w.u32(kMeshesTag);
  w.u32(count32(scene.meshes.size()));
  for (const Mesh& m : scene.meshes) {
    put_str(w, m.name);
    put_str(w, m.source);
    w.u64(m.dropped_degenerate);
    w.raw(&m.world_from_object, sizeof(glm::mat4));
    put_array(w, m.positions);
    put_array(w, m.normals);
    put_array(w, m.triangles);
    put_array(w, m.material_ids);
    put_array(w, m.source_index);
  }

  const Animation& anim = scene.animation;
  w.u32(kAnimationTag);
  w.i32(anim.frame_begin);
  w.i32(anim.frame_end);
  w.u32(count32(anim.camera.size()));
  for (const CameraKey& key : anim.camera) {
    w.i32(key.frame);
    put_camera(w, key.camera);
  }
  w.u32(count32(anim.meshes.size()));
  for (const MeshTrack& track : anim.meshes) {
    w.u32(track.mesh);
    w.u32(count32(track.keys.size()));
    for (const TransformKey& key : track.keys) {
      w.i32(key.frame);
      put_vec3(w, key.transform.translate);
      w.f32(key.transform.rotate.w);
      w.f32(key.transform.rotate.x);
      w.f32(key.transform.rotate.y);
      w.f32(key.transform.rotate.z);
      put_vec3(w, key.transform.scale);
    }
  }
  w.u32(count32(anim.lights.size()));
  for (const LightTrack& track : anim.lights) {
    w.u32(track.light);
    w.u32(count32(track.keys.size()));
    for (const LightKey& key : track.keys) {
      w.i32(key.frame);
      put_vec3(w, key.position);
    }
  }
  return out;
}

Scene deserialize_scene(std::span<const std::uint8_t> bytes, const std::string& what) {
  return SceneDecoder(bytes, what).decode();
}

}  // namespace rtc
