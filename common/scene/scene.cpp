// Scene queries and animation evaluation (double-precision interpolation, rounded once).
// Rotations interpolate with det_math, not glm::slerp: glm calls libm acos and sin, which glibc
// dispatches per CPU, and every worker evaluates poses itself.
#include "common/scene/scene.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "common/base/error.h"
#include "common/math/det_math.h"

namespace rtc {
namespace {

glm::dmat4 compose(const glm::dvec3& translate, const glm::dquat& rotate, const glm::dvec3& scale) {
  glm::dmat4 m = glm::mat4_cast(glm::normalize(rotate));
  m[0] *= scale.x;
  m[1] *= scale.y;
  m[2] *= scale.z;
  m[3] = glm::dvec4(translate, 1.0);
  return m;
}

glm::dquat to_double(const glm::quat& q) { return glm::dquat(q.w, q.x, q.y, q.z); }

/// The keys around `frame`: indices i0 <= i1 and the weight of i1 (0 when holding a key).
template <typename Key>
void bracket(const std::vector<Key>& keys, int frame, std::size_t& i0, std::size_t& i1, double& t) {
  i0 = i1 = 0;
  t = 0.0;
  if (frame <= keys.front().frame) return;
  if (frame >= keys.back().frame) {
    i0 = i1 = keys.size() - 1;
    return;
  }
  std::size_t k = 0;
  while (keys[k + 1].frame <= frame) ++k;
  i0 = k;
  if (keys[k].frame == frame) {
    i1 = k;
    return;
  }
  i1 = k + 1;
  t = static_cast<double>(frame - keys[k].frame) /
      static_cast<double>(keys[k + 1].frame - keys[k].frame);
}

glm::dvec3 mix3(const glm::vec3& a, const glm::vec3& b, double t) {
  return glm::dvec3(a) * (1.0 - t) + glm::dvec3(b) * t;
}

}  // namespace

void check_render_settings(const RenderSettings& s) {
  if (s.max_depth < 0 || s.max_depth > 64) {
    throw Error("render settings: max_depth must be in [0, 64], got " +
                std::to_string(s.max_depth));
  }
  if (!(s.min_weight >= 0.0f) || !(s.min_weight <= 1.0f)) {
    throw Error("render settings: min_weight must be in [0, 1], got " +
                std::to_string(s.min_weight));
  }
  if (s.spp < 1 || s.spp > 4096) {
    throw Error("render settings: spp must be in [1, 4096], got " + std::to_string(s.spp));
  }
  if (s.intersector != Intersector::Wald && s.intersector != Intersector::Watertight) {
    throw Error("render settings: intersector must be 0 (wald) or 1 (watertight), got " +
                std::to_string(static_cast<int>(s.intersector)));
  }
}

const char* intersector_name(Intersector intersector) {
  return intersector == Intersector::Watertight ? "watertight" : "wald";
}

glm::dquat slerp_shortest(const glm::dquat& a, const glm::dquat& b, double t) {
  // q and -q are the same rotation: take the one within 90 degrees (in 4D) of a.
  const glm::dquat c = glm::dot(a, b) < 0.0 ? -b : b;
  // The 4D angle between a and c from the chord lengths |a - c| = 2 sin(theta / 2) and
  // |a + c| = 2 cos(theta / 2): well conditioned for every angle, unlike acos(dot(a, c)).
  const double theta = 2.0 * det_atan2(glm::length(a - c), glm::length(a + c));
  if (theta < 1e-6) {
    // Nearly equal: normalised lerp differs from slerp by O(theta^3), below 1e-18.
    return glm::normalize(a * (1.0 - t) + c * t);
  }
  const double sin_theta = det_sin(theta);
  return a * (det_sin((1.0 - t) * theta) / sin_theta) + c * (det_sin(t * theta) / sin_theta);
}

glm::dquat rotation_deg_axis(double degrees, const glm::dvec3& unit_axis) {
  // Exact reduction first (fmod is exact): a turn of 720 degrees is the identity quaternion,
  // so huge angles keep their meaning instead of losing it in radians.
  const double half = std::fmod(degrees, 720.0) * (3.14159265358979323846 / 360.0);
  const double s = det_sin(half);
  return glm::dquat(det_cos(half), unit_axis.x * s, unit_axis.y * s, unit_axis.z * s);
}

glm::mat4 Transform::matrix() const {
  return glm::mat4(compose(glm::dvec3(translate), to_double(rotate), glm::dvec3(scale)));
}

std::uint64_t Scene::triangle_count() const {
  std::uint64_t n = 0;
  for (const Mesh& mesh : meshes) n += mesh.triangles.size();
  return n;
}

Aabb Scene::bounds() const {
  Aabb box;
  const FramePose pose = pose_at(*this, animation.frame_begin);
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    const Mesh& mesh = meshes[m];
    const glm::mat4& world = pose.world_from_object[m];
    std::vector<bool> used(mesh.positions.size(), false);
    for (const glm::uvec3& t : mesh.triangles) used[t.x] = used[t.y] = used[t.z] = true;
    const bool identity = world == glm::mat4(1.0f);
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
      if (!used[i]) continue;
      box.extend(identity ? mesh.positions[i]
                          : glm::vec3(world * glm::vec4(mesh.positions[i], 1.0f)));
    }
  }
  return box;
}

Camera camera_at(const Scene& scene, int frame) {
  const Animation& anim = scene.animation;
  Camera camera = scene.camera;
  if (!anim.camera.empty()) {
    std::size_t i0 = 0, i1 = 0;
    double t = 0.0;
    bracket(anim.camera, frame, i0, i1, t);
    const Camera& a = anim.camera[i0].camera;
    const Camera& b = anim.camera[i1].camera;
    camera.eye = glm::vec3(mix3(a.eye, b.eye, t));
    camera.look_at = glm::vec3(mix3(a.look_at, b.look_at, t));
    camera.up = glm::vec3(mix3(a.up, b.up, t));
    camera.vfov_deg = static_cast<float>(double(a.vfov_deg) * (1.0 - t) + double(b.vfov_deg) * t);
  }
  return camera;
}

std::string frames_outside_animation_note(const Scene& scene, int first, int last) {
  const Animation& a = scene.animation;
  if (a.camera.empty() && a.meshes.empty() && a.lights.empty()) return {};
  // Keys may lie outside the declared range, and the picture changes up to the last of them.
  int lo = a.frame_begin, hi = a.frame_end;
  const auto span = [&](const auto& keys) {
    for (const auto& key : keys) {
      lo = std::min(lo, key.frame);
      hi = std::max(hi, key.frame);
    }
  };
  span(a.camera);
  for (const MeshTrack& t : a.meshes) span(t.keys);
  for (const LightTrack& t : a.lights) span(t.keys);
  if (first >= lo && last <= hi) return {};
  const auto range = [](int from, int to) {
    return from == to ? "frame " + std::to_string(from) : "frames " + std::to_string(from) + "-" + std::to_string(to);
  };
  std::string note = range(first, last) + (first == last ? " lies" : " reach") + " outside the scene's animation (" +
                     range(lo, hi) + ", its range and keys), where every track holds its nearest key:";
  if (first < lo) note += " frames before " + std::to_string(lo) + " show frame " + std::to_string(lo);
  if (last > hi) {
    if (first < lo) note += ",";
    note += " frames after " + std::to_string(hi) + " show frame " + std::to_string(hi);
  }
  return note;
}

void check_cameras(const Scene& scene, int first, int last, const std::string& scene_name) {
  const auto check = [&](long long frame) {
    try {
      (void)CameraRays(camera_at(scene, static_cast<int>(frame)), scene.width, scene.height);
    } catch (const Error& e) {
      throw Error(scene_name + ": frame " + std::to_string(frame) + ": " + e.what());
    }
  };
  check(first);
  const std::vector<CameraKey>& keys = scene.animation.camera;
  if (keys.empty()) return;
  // Outside its keys the camera holds the nearest one: only the keyed span can differ from
  // `first`'s camera.
  const long long from = std::max(first, keys.front().frame);
  const long long to = std::min(last, keys.back().frame);
  if (last > to) check(last);
  if (from > to) return;
  constexpr long long kEveryFrameUpTo = 1 << 20;  // well under a second
  if (to - from < kEveryFrameUpTo) {
    for (long long frame = from; frame <= to; ++frame) check(frame);
    return;
  }
  // A longer span (the scene format allows a billion frames), segment by segment between keys.
  // There eye, look_at, up and vfov move linearly, so vfov is in range wherever it is at both
  // ends, and a camera goes bad only near the t where the view (look_at - eye, linear in t) is
  // shortest, where up is shortest, or where up is nearest to parallel to it: those frames, found in closed
  // form and by a scan, are checked with two frames either side, besides the segment's ends.
  // (rtc-master also gives up on errors every worker reports, should this miss a frame.)
  for (std::size_t k = 0; k + 1 < keys.size(); ++k) {
    const long long ka = keys[k].frame, kb = keys[k + 1].frame;
    const long long a = std::max(from, ka), b = std::min(to, kb);
    if (a > b) continue;
    const auto near = [&](double t) {
      const double f = std::round(static_cast<double>(ka) + t * static_cast<double>(kb - ka));
      for (long long g = static_cast<long long>(f) - 2; g <= static_cast<long long>(f) + 2; ++g) {
        if (g >= a && g <= b) check(g);
      }
    };
    near(0.0);
    near(1.0);
    check(a);
    check(b);
    const Camera& c0 = keys[k].camera;
    const Camera& c1 = keys[k + 1].camera;
    const glm::dvec3 v0 = glm::dvec3(c0.look_at) - glm::dvec3(c0.eye);
    const glm::dvec3 dv = glm::dvec3(c1.look_at) - glm::dvec3(c1.eye) - v0;
    if (glm::dot(dv, dv) > 0.0) near(std::clamp(-glm::dot(v0, dv) / glm::dot(dv, dv), 0.0, 1.0));
    const glm::dvec3 u0(c0.up), du = glm::dvec3(c1.up) - u0;
    // Where up is shortest (zero, if it passes through it): the scan below cannot see a zero,
    // which is a single point of its measure.
    if (glm::dot(du, du) > 0.0) near(std::clamp(-glm::dot(u0, du) / glm::dot(du, du), 0.0, 1.0));
    // The squared sine of the angle between the view and up at t, which camera_problem requires
    // above zero: small where up lines up with the view; 0 where either is zero.
    const auto sine2 = [&](double t) {
      const glm::dvec3 v = v0 + t * dv, u = u0 + t * du;
      const double vv_uu = glm::dot(v, v) * glm::dot(u, u);
      return vv_uu > 0.0 ? glm::dot(glm::cross(v, u), glm::cross(v, u)) / vv_uu : 0.0;
    };
    constexpr int kScan = 4096;
    int best = 0;
    double best_value = sine2(0.0);
    for (int i = 1; i <= kScan; ++i) {
      if (const double value = sine2(static_cast<double>(i) / kScan); value < best_value) {
        best = i;
        best_value = value;
      }
    }
    double lo = std::max(0, best - 1) / static_cast<double>(kScan);
    double hi = std::min(kScan, best + 1) / static_cast<double>(kScan);
    for (int i = 0; i < 100; ++i) {  // golden-section search for the minimum within [lo, hi]
      const double m1 = lo + (hi - lo) * 0.381966011250105, m2 = hi - (hi - lo) * 0.381966011250105;
      if (sine2(m1) < sine2(m2)) {
        hi = m2;
      } else {
        lo = m1;
      }
    }
    near(0.5 * (lo + hi));
  }
}

FramePose pose_at(const Scene& scene, int frame) {
  FramePose pose;
  pose.frame = frame;
  const Animation& anim = scene.animation;

  pose.camera = camera_at(scene, frame);

  pose.world_from_object.reserve(scene.meshes.size());
  for (const Mesh& mesh : scene.meshes) pose.world_from_object.push_back(mesh.world_from_object);
  for (const MeshTrack& track : anim.meshes) {
    if (track.mesh >= scene.meshes.size() || track.keys.empty()) continue;
    std::size_t i0 = 0, i1 = 0;
    double t = 0.0;
    bracket(track.keys, frame, i0, i1, t);
    const Transform& a = track.keys[i0].transform;
    const Transform& b = track.keys[i1].transform;
    if (i0 == i1 || a == b) {
      // On or outside a key, or between equal keys: that key, exactly (interpolating equal
      // keys may round differently from frame to frame, and a held mesh must not move).
      pose.world_from_object[track.mesh] = a.matrix();
      continue;
    }
    const glm::dquat rotation = slerp_shortest(glm::normalize(to_double(a.rotate)),
                                               glm::normalize(to_double(b.rotate)), t);
    pose.world_from_object[track.mesh] =
        glm::mat4(compose(mix3(a.translate, b.translate, t), rotation, mix3(a.scale, b.scale, t)));
  }

  pose.lights = scene.lights;
  for (const LightTrack& track : anim.lights) {
    if (track.light >= scene.lights.size() || track.keys.empty()) continue;
    std::size_t i0 = 0, i1 = 0;
    double t = 0.0;
    bracket(track.keys, frame, i0, i1, t);
    pose.lights[track.light].position =
        glm::vec3(mix3(track.keys[i0].position, track.keys[i1].position, t));
  }
  return pose;
}

std::vector<bool> moving_meshes(const Scene& scene) {
  std::vector<bool> moving(scene.meshes.size(), false);
  for (const MeshTrack& track : scene.animation.meshes) {
    if (track.mesh >= scene.meshes.size() || track.keys.empty()) continue;
    for (const TransformKey& key : track.keys) {
      if (!(key.transform == track.keys.front().transform)) moving[track.mesh] = true;
    }
  }
  return moving;
}

}  // namespace rtc
