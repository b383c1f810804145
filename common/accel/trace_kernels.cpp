// Per-ISA ray-stream kernels behind rtc::TraceKernels (compiled once per ISA).
#include <algorithm>

#include "common/accel/kd_traverse.h"
#include "common/accel/trace.h"

RTC_ISA_BEGIN
namespace rtc::RTC_ISA_NS {
namespace {

constexpr int kWidth = RTC_ISA_WIDTH;  // 4 (SSE4.2), 8 (AVX2) or 16 (AVX-512)

template <int N>
void load(const RayQuery* rays, std::size_t count, RayPacket<N>& p, vbool<N>& active) {
  RayLanes<N> lanes;
  unsigned mask = 0;
  for (int i = 0; i < N; ++i) {
    // Lanes past the end repeat the last ray (masked off) so they never slow the packet down.
    lanes.set(i, rays[std::min<std::size_t>(static_cast<std::size_t>(i), count - 1)]);
    if (static_cast<std::size_t>(i) < count) mask |= 1u << i;
  }
  p = lanes.packet();
  active = vbool<N>::from_bits(mask);
}

template <int N>
void intersect_stream(const KdTree& tree, const RayQuery* rays, RayHit* hits, std::size_t count) {
  for (std::size_t first = 0; first < count; first += N) {
    const std::size_t n = std::min<std::size_t>(N, count - first);
    RayPacket<N> p;
    vbool<N> active;
    load<N>(rays + first, n, p, active);
    HitPacket<N> h{p.t_max, vfloat<N>(0.0f), vfloat<N>(0.0f), vint<N>(-1)};
    intersect<N>(tree, p, active, h);
    for (std::size_t i = 0; i < n; ++i) {
      const int lane = static_cast<int>(i);
      hits[first + i] = RayHit{h.t.lane(lane), h.beta.lane(lane), h.gamma.lane(lane),
                               static_cast<std::uint32_t>(h.prim.lane(lane))};
    }
  }
}

template <int N>
void occluded_stream(const KdTree& tree, const RayQuery* rays, std::uint8_t* out, std::size_t count) {
  for (std::size_t first = 0; first < count; first += N) {
    const std::size_t n = std::min<std::size_t>(N, count - first);
    RayPacket<N> p;
    vbool<N> active;
    load<N>(rays + first, n, p, active);
    const vbool<N> occ = occluded<N>(tree, p, active);
    for (std::size_t i = 0; i < n; ++i) out[first + i] = occ.lane(static_cast<int>(i)) ? 1 : 0;
  }
}

void intersect_entry(const KdTree& tree, const RayQuery* rays, RayHit* hits, std::size_t count,
                     bool use_packets) {
  if (use_packets) {
    intersect_stream<kWidth>(tree, rays, hits, count);
  } else {
    intersect_stream<1>(tree, rays, hits, count);
  }
}

void occluded_entry(const KdTree& tree, const RayQuery* rays, std::uint8_t* out, std::size_t count,
                    bool use_packets) {
  if (use_packets) {
    occluded_stream<kWidth>(tree, rays, out, count);
  } else {
    occluded_stream<1>(tree, rays, out, count);
  }
}

}  // namespace

const TraceKernels& trace_kernels_for_isa() {
  static const TraceKernels kernels{Isa::RTC_ISA_ENUM, kWidth, &intersect_entry, &occluded_entry};
  return kernels;
}

}  // namespace rtc::RTC_ISA_NS
RTC_ISA_END
