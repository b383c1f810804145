// Embree 3 oracle: same triangles, same rays, Embree's answer.
#include "tests/support/embree_oracle.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "common/base/timer.h"

namespace rtc::test {

struct EmbreeScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
};

namespace {

void fill1(const RayQuery& q, RTCRay& r) {
  r.org_x = q.org.x;
  r.org_y = q.org.y;
  r.org_z = q.org.z;
  r.dir_x = q.dir.x;
  r.dir_y = q.dir.y;
  r.dir_z = q.dir.z;
  r.tnear = q.t_min;
  r.tfar = q.t_max;
  r.time = 0.0f;
  r.mask = 0xFFFFFFFFu;
  r.id = 0;
  r.flags = 0;
}

template <int W, typename RH>
void intersect_packets(RTCScene scene, const RayQuery* rays, RayHit* hits, std::size_t count) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  alignas(64) RH rh;
  alignas(64) int valid[W];
  for (std::size_t first = 0; first < count; first += W) {
    const std::size_t n = std::min<std::size_t>(W, count - first);
    for (int i = 0; i < W; ++i) {
      const bool ok = static_cast<std::size_t>(i) < n;
      valid[i] = ok ? -1 : 0;
      const RayQuery& q = rays[first + (ok ? static_cast<std::size_t>(i) : 0)];
      rh.ray.org_x[i] = q.org.x;
      rh.ray.org_y[i] = q.org.y;
      rh.ray.org_z[i] = q.org.z;
      rh.ray.dir_x[i] = q.dir.x;
      rh.ray.dir_y[i] = q.dir.y;
      rh.ray.dir_z[i] = q.dir.z;
      rh.ray.tnear[i] = q.t_min;
      rh.ray.tfar[i] = q.t_max;
      rh.ray.time[i] = 0.0f;
      rh.ray.mask[i] = 0xFFFFFFFFu;
      rh.ray.id[i] = 0;
      rh.ray.flags[i] = 0;
      rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.primID[i] = RTC_INVALID_GEOMETRY_ID;
    }
    if constexpr (W == 4) rtcIntersect4(valid, scene, &ctx, &rh);
    if constexpr (W == 8) rtcIntersect8(valid, scene, &ctx, &rh);
    if constexpr (W == 16) rtcIntersect16(valid, scene, &ctx, &rh);
    for (std::size_t i = 0; i < n; ++i) {
      const bool hit = rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
      hits[first + i] = RayHit{rh.ray.tfar[i], rh.hit.u[i], rh.hit.v[i], hit ? rh.hit.primID[i] : kNoHit};
    }
  }
}

template <int W, typename R>
void occluded_packets(RTCScene scene, const RayQuery* rays, std::uint8_t* out, std::size_t count) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  alignas(64) R r;
  alignas(64) int valid[W];
  for (std::size_t first = 0; first < count; first += W) {
    const std::size_t n = std::min<std::size_t>(W, count - first);
    for (int i = 0; i < W; ++i) {
      const bool ok = static_cast<std::size_t>(i) < n;
      valid[i] = ok ? -1 : 0;
      const RayQuery& q = rays[first + (ok ? static_cast<std::size_t>(i) : 0)];
      r.org_x[i] = q.org.x;
      r.org_y[i] = q.org.y;
      r.org_z[i] = q.org.z;
      r.dir_x[i] = q.dir.x;
      r.dir_y[i] = q.dir.y;
      r.dir_z[i] = q.dir.z;
      r.tnear[i] = q.t_min;
      r.tfar[i] = q.t_max;
      r.time[i] = 0.0f;
      r.mask[i] = 0xFFFFFFFFu;
      r.id[i] = 0;
      r.flags[i] = 0;
    }
    if constexpr (W == 4) rtcOccluded4(valid, scene, &ctx, &r);
    if constexpr (W == 8) rtcOccluded8(valid, scene, &ctx, &r);
    if constexpr (W == 16) rtcOccluded16(valid, scene, &ctx, &r);
    for (std::size_t i = 0; i < n; ++i) out[first + i] = r.tfar[i] < 0.0f ? 1 : 0;
  }
}

}  // namespace

EmbreeScene::EmbreeScene(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                         bool robust, bool high_quality)
    : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice(nullptr);
  if (impl_->device == nullptr) throw std::runtime_error("Embree: rtcNewDevice failed");
  Timer timer;
  impl_->scene = rtcNewScene(impl_->device);
  if (robust) rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(impl_->scene, high_quality ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM);
  RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  if (high_quality) rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_HIGH);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                        3 * sizeof(float), positions.size()));
  std::memcpy(v, positions.data(), positions.size() * sizeof(glm::vec3));
  auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                             3 * sizeof(unsigned), triangles.size()));
  std::memcpy(idx, triangles.data(), triangles.size() * sizeof(glm::uvec3));
  rtcCommitGeometry(geom);
  rtcAttachGeometry(impl_->scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(impl_->scene);
  build_ms_ = timer.elapsed_ms();
}

EmbreeScene::~EmbreeScene() {
  if (impl_->scene != nullptr) rtcReleaseScene(impl_->scene);
  if (impl_->device != nullptr) rtcReleaseDevice(impl_->device);
}

bool EmbreeScene::supports(EmbreeMode mode) const {
  switch (mode) {
    case EmbreeMode::Single:
      return true;
    case EmbreeMode::Packet4:
      return rtcGetDeviceProperty(impl_->device, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED) != 0;
    case EmbreeMode::Packet8:
      return rtcGetDeviceProperty(impl_->device, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED) != 0;
    case EmbreeMode::Packet16:
      return rtcGetDeviceProperty(impl_->device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) != 0;
  }
  return false;
}

void EmbreeScene::intersect(const RayQuery* rays, RayHit* hits, std::size_t count, EmbreeMode mode) const {
  switch (mode) {
    case EmbreeMode::Single: {
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
      for (std::size_t i = 0; i < count; ++i) {
        RTCRayHit rh;
        fill1(rays[i], rh.ray);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(impl_->scene, &ctx, &rh);
        const bool hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
        hits[i] = RayHit{rh.ray.tfar, rh.hit.u, rh.hit.v, hit ? rh.hit.primID : kNoHit};
      }
      return;
    }
    case EmbreeMode::Packet4:
      intersect_packets<4, RTCRayHit4>(impl_->scene, rays, hits, count);
      return;
    case EmbreeMode::Packet8:
      intersect_packets<8, RTCRayHit8>(impl_->scene, rays, hits, count);
      return;
    case EmbreeMode::Packet16:
      intersect_packets<16, RTCRayHit16>(impl_->scene, rays, hits, count);
      return;
  }
}

void EmbreeScene::occluded(const RayQuery* rays, std::uint8_t* out, std::size_t count, EmbreeMode mode) const {
  switch (mode) {
    case EmbreeMode::Single: {
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
      for (std::size_t i = 0; i < count; ++i) {
        RTCRay r;
        fill1(rays[i], r);
        rtcOccluded1(impl_->scene, &ctx, &r);
        out[i] = r.tfar < 0.0f ? 1 : 0;
      }
      return;
    }
    case EmbreeMode::Packet4:
      occluded_packets<4, RTCRay4>(impl_->scene, rays, out, count);
      return;
    case EmbreeMode::Packet8:
      occluded_packets<8, RTCRay8>(impl_->scene, rays, out, count);
      return;
    case EmbreeMode::Packet16:
      occluded_packets<16, RTCRay16>(impl_->scene, rays, out, count);
      return;
  }
}

std::string EmbreeScene::mode_name(EmbreeMode mode) {
  switch (mode) {
    case EmbreeMode::Single:
      return "embree-1";
    case EmbreeMode::Packet4:
      return "embree-4";
    case EmbreeMode::Packet8:
      return "embree-8";
    case EmbreeMode::Packet16:
      return "embree-16";
  }
  return "embree";
}

}  // namespace rtc::test
