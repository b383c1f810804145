// Pixels must be the same bits on every x86-64 CPU, but glibc picks FMA or non-FMA variants of
// sin, cos, tan, acos, atan2 at run time (common/math/det_math.h). This binary interposes those
// libm functions: each counts its calls and forwards to libm, so a test can assert that
// pose_at, the scene-JSON rotations, NFF tessellation, the automatic camera and the default
// scene call none of them.
#include <gtest/gtest.h>

#include <dlfcn.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "common/math/det_math.h"
#include "common/scene/load.h"
#include "common/scene/mesh_file.h"
#include "test_files.h"

namespace {

std::atomic<long> g_libm_calls{0};

template <typename F>
F libm_symbol(const char* name) {
  void* address = dlsym(RTLD_NEXT, name);
  if (address == nullptr) {
    std::fprintf(stderr, "determinism_test: libm has no %s\n", name);
    std::abort();
  }
  F f = nullptr;
  std::memcpy(&f, &address, sizeof f);
  return f;
}

}  // namespace

// Definitions in the executable take precedence over libm's for every caller, the scene
// library included.
#define RTC_COUNTED_LIBM_1(name, T)                                  \
  extern "C" T name(T x) noexcept {                                  \
    static const auto real = libm_symbol<T (*)(T)>(#name);           \
    g_libm_calls.fetch_add(1, std::memory_order_relaxed);            \
    return real(x);                                                  \
  }
#define RTC_COUNTED_LIBM_2(name, T)                                  \
  extern "C" T name(T y, T x) noexcept {                             \
    static const auto real = libm_symbol<T (*)(T, T)>(#name);        \
    g_libm_calls.fetch_add(1, std::memory_order_relaxed);            \
    return real(y, x);                                               \
  }
#define RTC_COUNTED_LIBM_SINCOS(name, T)                             \
  extern "C" void name(T x, T* s, T* c) noexcept {                   \
    static const auto real = libm_symbol<void (*)(T, T*, T*)>(#name); \
    g_libm_calls.fetch_add(1, std::memory_order_relaxed);            \
    real(x, s, c);                                                   \
  }

RTC_COUNTED_LIBM_1(sin, double)
RTC_COUNTED_LIBM_1(cos, double)
RTC_COUNTED_LIBM_1(tan, double)
RTC_COUNTED_LIBM_1(asin, double)
RTC_COUNTED_LIBM_1(acos, double)
RTC_COUNTED_LIBM_1(atan, double)
RTC_COUNTED_LIBM_2(atan2, double)
RTC_COUNTED_LIBM_2(pow, double)
RTC_COUNTED_LIBM_SINCOS(sincos, double)
RTC_COUNTED_LIBM_1(sinf, float)
RTC_COUNTED_LIBM_1(cosf, float)
RTC_COUNTED_LIBM_1(tanf, float)
RTC_COUNTED_LIBM_1(acosf, float)
RTC_COUNTED_LIBM_2(atan2f, float)
RTC_COUNTED_LIBM_2(powf, float)
RTC_COUNTED_LIBM_SINCOS(sincosf, float)

#undef RTC_COUNTED_LIBM_1
#undef RTC_COUNTED_LIBM_2
#undef RTC_COUNTED_LIBM_SINCOS

namespace rtc {
namespace {

using test::TempDir;

/// libm calls made since construction.
class LibmCalls {
 public:
  LibmCalls() : start_(g_libm_calls.load()) {}
  [[nodiscard]] long count() const { return g_libm_calls.load() - start_; }

 private:
  long start_;
};

TEST(Determinism, TheGuardCountsLibmCalls) {
  volatile double x = 0.5;  // not folded at compile time
  const LibmCalls calls;
  const double s = std::sin(x);
  const double a = std::acos(x);
  EXPECT_EQ(calls.count(), 2) << "interposition does not work; the other tests prove nothing";
  EXPECT_EQ(s, std::sin(0.5));
  EXPECT_EQ(a, std::acos(0.5));
}

TEST(Determinism, PoseAtCallsNoLibm) {
  Scene scene = test::one_triangle_scene();
  scene.animation.frame_end = 10;
  MeshTrack track;
  Transform a, b;
  b.rotate = glm::quat(0.6f, 0.0f, 0.8f, 0.0f);
  track.keys = {TransformKey{0, a}, TransformKey{10, b}};
  scene.animation.meshes.push_back(track);
  const LibmCalls calls;
  const FramePose pose = pose_at(scene, 3);
  EXPECT_EQ(calls.count(), 0);
  EXPECT_NE(pose.world_from_object[0], glm::mat4(1.0f));
}

TEST(Determinism, SceneJsonRotationsCallNoLibm) {
  TempDir dir;
  (void)dir.write("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const auto json = dir.write("scene.json", R"({
    "meshes": [{"file": "tri.obj", "name": "t", "transform": {"rotate_deg_axis": [30, 0, 1, 1]}}],
    "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0]},
    "animation": {"frames": [0, 4], "meshes": [{"mesh": "t", "keys": [
      {"frame": 0}, {"frame": 4, "rotate_deg_axis": [100, 1, 0, 0]}]}]}})");
  const LibmCalls calls;
  const Scene scene = load_scene(json);
  const FramePose pose = pose_at(scene, 1);
  EXPECT_EQ(calls.count(), 0);
  EXPECT_NE(pose.world_from_object[0], scene.meshes[0].world_from_object);
}

TEST(Determinism, NffTessellationAndAutomaticCameraCallNoLibm) {
  TempDir dir;
  const auto nff = dir.write("s.nff", "s 0 0 0 1\nc 0 0 0 1 0 0 2 0.5\n");
  const auto obj = dir.write("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const LibmCalls calls;
  const MeshFile file = load_nff(nff);
  Scene scene = load_scene(obj);
  scene.width = 100;  // narrower than tall: the horizontal field of view decides
  scene.height = 400;
  frame_automatically(scene);
  EXPECT_EQ(calls.count(), 0);
  EXPECT_EQ(file.mesh.triangles.size(), 192u + 32u);
}

TEST(Determinism, DefaultSceneCallsNoLibm) {
  const LibmCalls calls;
  const Scene scene = default_scene();
  const FramePose pose = pose_at(scene, 7);
  EXPECT_EQ(calls.count(), 0);
  EXPECT_EQ(pose.world_from_object.size(), scene.meshes.size());
}

}  // namespace
}  // namespace rtc
