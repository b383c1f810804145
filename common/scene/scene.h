// The scene model: meshes, materials, point lights, camera, image settings and animation.
// Loaders (scene JSON, OBJ/MTL, PLY, glTF, NFF) fill it; the renderer flattens it per frame.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "common/base/frame_range.h"
#include "common/math/aabb.h"
#include "common/math/camera.h"

namespace rtc {

/// Largest |coordinate| the loaders accept for world-space geometry after transforms (scene
/// JSON scale and translate, NFF sphere and cone extents): a little below FLT_MAX (3.4e38), so
/// the renderer's float transforms cannot round up to infinity. Beyond it loading fails with
/// an rtc::Error naming the field or line.
inline constexpr double kMaxWorldCoordinate = 3.0e38;

/// Largest frame number a scene may use (animation range and keys); frames are never negative
/// (output file names number frames from 0). Keeps differences of frame numbers within int.
inline constexpr int kMaxFrame = kMaxFrameNumber;

/// Phong material with a mirror term (Whitted). Colours are linear RGB.
struct Material {
  std::string name = "default";
  glm::vec3 diffuse{0.8f};   ///< Kd
  glm::vec3 specular{0.0f};  ///< Ks: highlight colour, and the mirror weight when reflective
  float shininess = 32.0f;   ///< Ns, Phong exponent (NFF values up to 1e5 mean "no highlight")
  glm::vec3 emission{0.0f};  ///< Ke, added unshadowed
  bool reflective = false;   ///< MTL illum 3 / NFF Ks > 0: mirror ray with weight `specular`
  float opacity = 1.0f;      ///< MTL d; recorded, the tracer treats every surface as opaque

  bool operator==(const Material&) const = default;
};

/// A point light without distance falloff (NFF / SPD convention).
struct PointLight {
  glm::vec3 position{0.0f};
  glm::vec3 color{1.0f};

  bool operator==(const PointLight&) const = default;
};

/// Rigid transform (plus uniform or per-axis scale), applied scale, then rotate, then translate.
struct Transform {
  glm::vec3 translate{0.0f};
  glm::quat rotate{1.0f, 0.0f, 0.0f, 0.0f};  ///< w, x, y, z
  glm::vec3 scale{1.0f};

  [[nodiscard]] glm::mat4 matrix() const;
  bool operator==(const Transform&) const = default;
};

/// A triangle mesh in object space. Triangles reference `positions`; degenerate triangles
/// are already dropped by the loader (counted in `dropped_degenerate`).
struct Mesh {
  std::string name;
  std::string source;                       ///< file it came from, for messages
  std::vector<glm::vec3> positions;
  /// Empty, or one per position (smooth shading, unit length). A vertex without a normal in
  /// the file (e.g. an OBJ polygon next to normal-carrying patches) has (0, 0, 0): use the
  /// geometric normal there.
  std::vector<glm::vec3> normals;
  std::vector<glm::uvec3> triangles;        ///< indices into positions
  std::vector<std::uint32_t> material_ids;  ///< one per triangle, index into Scene::materials
  /// One per triangle: its index in the input file's order after fan triangulation, counting
  /// the dropped degenerate ones (what `rtc-bench --dump` writes and the oracle compares).
  std::vector<std::uint32_t> source_index;
  std::uint64_t dropped_degenerate = 0;
  /// Static placement in the world (object space -> world space); animation tracks for this
  /// mesh replace it where they have keys.
  glm::mat4 world_from_object{1.0f};
};

/// Camera keyframe: the camera at `frame`; frames between keys interpolate linearly
/// (eye, look_at, up, vfov), frames outside the keyed range hold the nearest key.
struct CameraKey {
  int frame = 0;
  Camera camera;
};

/// Rigid-transform keyframe for one mesh; interpolation as CameraKey (rotation by slerp).
struct TransformKey {
  int frame = 0;
  Transform transform;
};

/// Light position keyframe.
struct LightKey {
  int frame = 0;
  glm::vec3 position{0.0f};
};

struct MeshTrack {
  std::uint32_t mesh = 0;  ///< index into Scene::meshes
  std::vector<TransformKey> keys;  ///< sorted by frame, at least one
};

struct LightTrack {
  std::uint32_t light = 0;  ///< index into Scene::lights
  std::vector<LightKey> keys;  ///< sorted by frame, at least one
};

/// Frames [frame_begin, frame_end] (inclusive) with optional camera, mesh and light tracks.
/// A static-camera sequence where only some meshes move is: no camera keys, some mesh tracks.
struct Animation {
  int frame_begin = 0;
  int frame_end = 0;
  std::vector<CameraKey> camera;  ///< empty: Scene::camera for every frame
  std::vector<MeshTrack> meshes;
  std::vector<LightTrack> lights;
};

/// The ray/triangle test. Numbers are the scene bytes' (protocol/protocol.md).
enum class Intersector : std::uint8_t {
  Wald = 0,        ///< Wald's projected barycentric test (2001): fast, rays may slip through shared edges
  Watertight = 1,  ///< Woop, Benthin and Wald's watertight test (2013)
};

/// "wald" or "watertight" (the JSON and CLI spelling).
[[nodiscard]] const char* intersector_name(Intersector intersector);

/// Settings that trade time for accuracy; the scene file may set them, the CLI may override.
struct RenderSettings {
  /// Reflection bounces after the primary hit, and the ray-weight cutoff: 8 and 0.001, from the
  /// time/error sweep (tests/bench/results/sweep). On spd-balls-s3, the shared scene with the
  /// deepest interreflections, 1.05% of pixels were off the reference by more than 1/255 with
  /// the former 5 and 0.01, 0.72% at depth 6 or more, 0.65% with the cutoff at 0.001 as well
  /// (the converged figure: depth 64 with no cutoff gives the same), for 2% more reflection
  /// rays; every other shared scene has converged at depth 2.
  int max_depth = 8;
  float min_weight = 0.001f;  ///< ray-weight cutoff: reflections weaker than this are not traced
  int spp = 1;                ///< samples per pixel (deterministic pattern)
  Intersector intersector = Intersector::Wald;  ///< changes pixels at shared edges, so it travels with the scene
};

/// Throws rtc::Error("render settings: <field> must be in [lo, hi], got <value>") unless
/// max_depth is in [0, 64], min_weight in [0, 1], spp in [1, 4096] and intersector one of the
/// enum's values. The renderer and the scene deserializer both check with it.
void check_render_settings(const RenderSettings& settings);

/// A whole scene. Value type; copying copies the meshes.
struct Scene {
  std::string name = "scene";
  std::filesystem::path source;  ///< the file it was loaded from (empty when built in)
  std::vector<Mesh> meshes;
  std::vector<Material> materials;  ///< at least one; material 0 is the default
  std::vector<PointLight> lights;
  Camera camera;
  int width = 512;
  int height = 512;
  glm::vec3 background{0.0f};
  glm::vec3 ambient{0.1f};  ///< ambient light, multiplied by the diffuse colour
  RenderSettings settings;
  Animation animation;
  /// The camera was placed by the automatic framing (no camera in the file): a tool that
  /// changes width/height should frame again (see set_resolution in load.h).
  bool camera_automatic = false;

  /// Number of triangles over all meshes (after degenerate dropping).
  [[nodiscard]] std::uint64_t triangle_count() const;
  /// World-space bounds of the static placement (frame_begin).
  [[nodiscard]] Aabb bounds() const;
};

/// The scene as it stands at one frame: transforms, camera and lights evaluated.
struct FramePose {
  int frame = 0;
  Camera camera;
  std::vector<glm::mat4> world_from_object;  ///< one per mesh
  std::vector<PointLight> lights;
};

/// The camera at `frame` (pose_at's camera).
[[nodiscard]] Camera camera_at(const Scene& scene, int frame);

/// Throws rtc::Error ("<scene_name>: frame N: camera: ...") for the first frame in [first, last]
/// whose camera CameraRays refuses (eye on look_at, up along the view, vfov out of (0, 180)), so
/// that a camera animated into such a pose is refused before anything is rendered, not by a
/// worker in the middle of a run. Visits only the frames its keys span.
void check_cameras(const Scene& scene, int first, int last, const std::string& scene_name);

/// A note for frames [first, last] that reach outside an animated scene's range (a camera,
/// mesh or light track): there every track holds its nearest key, so those frames repeat the
/// range's first or last picture, which is rarely what was meant. Empty for frames inside the
/// range, and for a scene with no tracks (its every frame is the same picture by design).
[[nodiscard]] std::string frames_outside_animation_note(const Scene& scene, int first, int last);

/// Evaluates the animation at `frame` (deterministic; double-precision interpolation, rotations
/// by slerp_shortest: the same bits on every CPU).
[[nodiscard]] FramePose pose_at(const Scene& scene, int frame);

/// Per mesh: whether its world transform may differ between frames, i.e. whether a track for
/// it has keys whose transforms are not all equal. pose_at gives a mesh for which this is false
/// the same world_from_object (bit for bit) at every frame.
[[nodiscard]] std::vector<bool> moving_meshes(const Scene& scene);

/// Spherical linear interpolation between unit quaternions a (t = 0) and b (t = 1) along the
/// shorter arc (b is negated when dot(a, b) < 0), normalised lerp when they are within 1e-6
/// radians. Agrees with glm::slerp to 1e-9 (glm's acos(dot) loses digits at small angles; this
/// takes the angle from atan2 of the chord lengths), and is built on det_math, so it gives the
/// same bits on every x86-64 CPU.
[[nodiscard]] glm::dquat slerp_shortest(const glm::dquat& a, const glm::dquat& b, double t);

/// The unit quaternion rotating by `degrees` about `unit_axis` (glm::angleAxis in degrees, on
/// det_math: the same bits on every CPU). The angle is reduced exactly modulo 720 degrees first.
[[nodiscard]] glm::dquat rotation_deg_axis(double degrees, const glm::dvec3& unit_axis);

}  // namespace rtc
