// Per-ISA ray-stream kernels behind rtc::TraceKernels (compiled once per ISA).
#include <algorithm>
#include <cstddef>

#include "common/accel/kd_traverse.h"
#include "common/accel/trace.h"

// GCC 12 takes the _mm512_undefined_ps() inside AVX-512 unpack and insert intrinsics for an
// uninitialised read: a "maybe" in optimised builds, and a certain one (-Wuninitialized, the
// `__Y = __Y` of _mm512_zextps256_ps512) under -fsanitize, which broke the asan and tsan presets.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

RTC_ISA_BEGIN
namespace rtc::RTC_ISA_NS {
namespace {

constexpr int kWidth = RTC_ISA_WIDTH;  // 4 (SSE4.2), 8 (AVX2) or 16 (AVX-512)

// transpose_rays: the N rays row[0..N-1] (32-byte RayQuery records: org, t_min, dir, t_max) as
// one packet, by vector loads and the unpack/shuffle 8x8 transpose. It replaced eight gathers
// per packet (AVX-512 and AVX2; SSE4.2 stored lane by lane), which on this AMD EPYC took as
// long as the 16-wide traversal itself on small scenes: 16-wide primary rays 1.6x on
// spd-teapot.
#if RTC_ISA_WIDTH == 16
inline void transpose_rays(const RayQuery* const* row, RayPacket<16>& p) {
  // Row k holds ray k in its low half and ray k + 8 in its high half; the 8x8 transposes of
  // both halves then give component a of rays 0-3 | 8-11 and 4-7 | 12-15, merged by one
  // two-source permute per component. Loads and shuffles only: gathers (and scalar stores read
  // back as vectors) cost far more.
  __m512 r[8];
  for (int k = 0; k < 8; ++k) {
    r[k] = _mm512_insertf32x8(_mm512_zextps256_ps512(_mm256_loadu_ps(&row[k]->org.x)),
                              _mm256_loadu_ps(&row[k + 8]->org.x), 1);
  }
  __m512 u[8];
  for (int h = 0; h < 2; ++h) {  // rows 0-3, rows 4-7
    const __m512 t0 = _mm512_unpacklo_ps(r[4 * h], r[4 * h + 1]);
    const __m512 t1 = _mm512_unpackhi_ps(r[4 * h], r[4 * h + 1]);
    const __m512 t2 = _mm512_unpacklo_ps(r[4 * h + 2], r[4 * h + 3]);
    const __m512 t3 = _mm512_unpackhi_ps(r[4 * h + 2], r[4 * h + 3]);
    u[4 * h + 0] = _mm512_shuffle_ps(t0, t2, 0x44);  // components 0 | 4
    u[4 * h + 1] = _mm512_shuffle_ps(t0, t2, 0xEE);  // 1 | 5
    u[4 * h + 2] = _mm512_shuffle_ps(t1, t3, 0x44);  // 2 | 6
    u[4 * h + 3] = _mm512_shuffle_ps(t1, t3, 0xEE);  // 3 | 7
  }
  const __m512i lo = _mm512_setr_epi32(0, 1, 2, 3, 16, 17, 18, 19, 8, 9, 10, 11, 24, 25, 26, 27);
  const __m512i hi = _mm512_setr_epi32(4, 5, 6, 7, 20, 21, 22, 23, 12, 13, 14, 15, 28, 29, 30, 31);
  __m512 c[8];
  for (int a = 0; a < 4; ++a) {
    c[a] = _mm512_permutex2var_ps(u[a], lo, u[4 + a]);
    c[a + 4] = _mm512_permutex2var_ps(u[a], hi, u[4 + a]);
  }
  for (int a = 0; a < 3; ++a) {
    p.org[a] = vfloat<16>(c[a]);
    p.dir[a] = vfloat<16>(c[4 + a]);
  }
  p.t_min = vfloat<16>(c[3]);
  p.t_max = vfloat<16>(c[7]);
}
#elif RTC_ISA_WIDTH == 8
inline void transpose_rays(const RayQuery* const* row, RayPacket<8>& p) {
  __m256 r[8];
  for (int k = 0; k < 8; ++k) r[k] = _mm256_loadu_ps(&row[k]->org.x);
  __m256 u[8];
  for (int h = 0; h < 2; ++h) {
    const __m256 t0 = _mm256_unpacklo_ps(r[4 * h], r[4 * h + 1]);
    const __m256 t1 = _mm256_unpackhi_ps(r[4 * h], r[4 * h + 1]);
    const __m256 t2 = _mm256_unpacklo_ps(r[4 * h + 2], r[4 * h + 3]);
    const __m256 t3 = _mm256_unpackhi_ps(r[4 * h + 2], r[4 * h + 3]);
    u[4 * h + 0] = _mm256_shuffle_ps(t0, t2, 0x44);
    u[4 * h + 1] = _mm256_shuffle_ps(t0, t2, 0xEE);
    u[4 * h + 2] = _mm256_shuffle_ps(t1, t3, 0x44);
    u[4 * h + 3] = _mm256_shuffle_ps(t1, t3, 0xEE);
  }
  __m256 c[8];
  for (int a = 0; a < 4; ++a) {
    c[a] = _mm256_permute2f128_ps(u[a], u[4 + a], 0x20);
    c[a + 4] = _mm256_permute2f128_ps(u[a], u[4 + a], 0x31);
  }
  for (int a = 0; a < 3; ++a) {
    p.org[a] = vfloat<8>(c[a]);
    p.dir[a] = vfloat<8>(c[4 + a]);
  }
  p.t_min = vfloat<8>(c[3]);
  p.t_max = vfloat<8>(c[7]);
}
#else
inline void transpose_rays(const RayQuery* const* row, RayPacket<4>& p) {
  __m128 a[4], b[4];  // org and t_min; dir and t_max
  for (int k = 0; k < 4; ++k) {
    a[k] = _mm_loadu_ps(&row[k]->org.x);
    b[k] = _mm_loadu_ps(&row[k]->dir.x);
  }
  _MM_TRANSPOSE4_PS(a[0], a[1], a[2], a[3]);
  _MM_TRANSPOSE4_PS(b[0], b[1], b[2], b[3]);
  for (int c = 0; c < 3; ++c) {
    p.org[c] = vfloat<4>(a[c]);
    p.dir[c] = vfloat<4>(b[c]);
  }
  p.t_min = vfloat<4>(a[3]);
  p.t_max = vfloat<4>(b[3]);
}
#endif

template <int N>
void load(const RayQuery* rays, std::size_t count, RayPacket<N>& p, vbool<N>& active) {
  // Lanes past the end repeat the last ray (masked off) so they never slow the packet down.
  const unsigned mask = (1u << std::min<std::size_t>(count, N)) - 1u;
  active = vbool<N>::from_bits(mask);
  if constexpr (N > 1) {
    static_assert(sizeof(RayQuery) == 32 && offsetof(RayQuery, t_min) == 12 && offsetof(RayQuery, dir) == 16 &&
                  offsetof(RayQuery, t_max) == 28);
    const RayQuery* row[N];
    for (int i = 0; i < N; ++i) row[i] = rays + std::min<std::size_t>(static_cast<std::size_t>(i), count - 1);
    transpose_rays(row, p);
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
    // (Transposing these into whole-record vector stores measured no faster.)
    for (std::size_t i = 0; i < n; ++i) hits[first + i] = RayHit{t[i], beta[i], gamma[i], static_cast<std::uint32_t>(prim[i])};
  }
}

template <int N>
void occluded_stream(const KdTree& tree, const RayQuery* rays, std::uint8_t* out, std::size_t count,
                     ShadowOrder order, ShadowOrderTally* tally) {
  ShadowOrderChooser chooser(order, tally);
  for (std::size_t first = 0; first < count; first += N) {
    const std::size_t n = std::min<std::size_t>(N, count - first);
    RayPacket<N> p;
    vbool<N> active;
    load<N>(rays + first, n, p, active);
    const unsigned occ = bits(occluded<N>(tree, p, active, chooser));
    for (std::size_t i = 0; i < n; ++i) out[first + i] = ((occ >> i) & 1u) != 0 ? 1 : 0;
  }
  chooser.flush();
}

void intersect_entry(const KdTree& tree, const RayQuery* rays, RayHit* hits, std::size_t count,
                     bool use_packets) {
  if (use_packets) {
    intersect_stream<kWidth>(tree, rays, hits, count);
  } else {
    intersect_stream<1>(tree, rays, hits, count);
  }
}

void occluded_in_order_entry(const KdTree& tree, const RayQuery* rays, std::uint8_t* out, std::size_t count,
                             bool use_packets, ShadowOrder order, ShadowOrderTally* tally) {
  if (use_packets) {
    occluded_stream<kWidth>(tree, rays, out, count, order, tally);
  } else {
    occluded_stream<1>(tree, rays, out, count, order, tally);
  }
}

void occluded_entry(const KdTree& tree, const RayQuery* rays, std::uint8_t* out, std::size_t count,
                    bool use_packets) {
  occluded_in_order_entry(tree, rays, out, count, use_packets, ShadowOrder::Auto, nullptr);
}

}  // namespace

const TraceKernels& trace_kernels_for_isa() {
  static const TraceKernels kernels{Isa::RTC_ISA_ENUM, kWidth, &intersect_entry, &occluded_entry,
                                    &occluded_in_order_entry};
  return kernels;
}

}  // namespace rtc::RTC_ISA_NS
RTC_ISA_END

#pragma GCC diagnostic pop
