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
  // Lanes past the end repeat the last ray (masked off) so they never slow the packet down.
  const unsigned mask = (1u << std::min<std::size_t>(count, N)) - 1u;
  active = vbool<N>::from_bits(mask);
  if constexpr (N >= 8) {
    // Gathers straight from the 32-byte records: scalar stores read back as vectors stall
    // store forwarding, which measured as a fifth of a 16-wide primary packet's time.
    static_assert(sizeof(RayQuery) == 8 * sizeof(float));
    alignas(64) std::int32_t index[N];
    for (int i = 0; i < N; ++i) index[i] = 8 * static_cast<std::int32_t>(std::min<std::size_t>(static_cast<std::size_t>(i), count - 1));
    const vint<N> idx = vint<N>::load(index);
    const float* base = &rays[0].org.x;
    for (int a = 0; a < 3; ++a) {
      p.org[a] = vfloat<N>::gather(base + a, idx.v);
      p.dir[a] = vfloat<N>::gather(base + 4 + a, idx.v);
    }
    p.t_min = vfloat<N>::gather(base + 3, idx.v);
    p.t_max = vfloat<N>::gather(base + 7, idx.v);
  } else {
    RayLanes<N> lanes;
    for (int i = 0; i < N; ++i) lanes.set(i, rays[std::min<std::size_t>(static_cast<std::size_t>(i), count - 1)]);
    p = lanes.packet();
  }
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
    alignas(64) float t[N], beta[N], gamma[N];
    alignas(64) std::int32_t prim[N];
    h.t.store(t);
    h.beta.store(beta);
    h.gamma.store(gamma);
    h.prim.store(prim);
    for (std::size_t i = 0; i < n; ++i) hits[first + i] = RayHit{t[i], beta[i], gamma[i], static_cast<std::uint32_t>(prim[i])};
  }
}

template <int N>
void occluded_stream(const KdTree& tree, const RayQuery* rays, std::uint8_t* out, std::size_t count) {
  for (std::size_t first = 0; first < count; first += N) {
    const std::size_t n = std::min<std::size_t>(N, count - first);
    RayPacket<N> p;
    vbool<N> active;
    load<N>(rays + first, n, p, active);
    const unsigned occ = bits(occluded<N>(tree, p, active));
    for (std::size_t i = 0; i < n; ++i) out[first + i] = ((occ >> i) & 1u) != 0 ? 1 : 0;
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
