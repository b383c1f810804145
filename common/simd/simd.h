// SIMD vocabulary for packet kernels: vfloat<N>, vint<N>, vbool<N>.
// N = 1 is the scalar reference; N = 4 is SSE; N = 8 is AVX2 and N = 16 AVX-512, defined only
// in the kernel objects of ISAs that have them (RTC_ISA_WIDTH, cmake/rtc_isa.cmake). Every
// operation has one meaning at every width (min/max return the second operand when either is
// NaN, exactly like minps/maxps; comparisons are ordered, false on NaN; no FMA, no approximate
// reciprocals), so a kernel written once over N gives the same bits at each width and ISA.
// Included only by kernel sources compiled per ISA (cmake/rtc_isa.cmake), inside
// rtc::RTC_ISA_NS, so that no inline function built with ISA flags leaks into other code.
#pragma once

#ifndef RTC_ISA_NS
#error "common/simd/simd.h is for kernel sources compiled per ISA (rtc_isa_kernels)"
#endif

#include <immintrin.h>

#include <cstdint>
#include <cstring>

#include "common/simd/isa_region.h"

RTC_ISA_BEGIN
namespace rtc::RTC_ISA_NS {

template <int N>
struct vfloat;
template <int N>
struct vint;
template <int N>
struct vbool;

// ---------------------------------------------------------------------------------------
// Vector types are trivially default-constructible, like the raw __m128/__m256/__m512 (a
// default-constructed value is unspecified until assigned). Zeroing default constructors were
// called out of line from the implicit constructors of PacketVec3/RayPacket/HitPacket, which
// GCC generates without the region's target: every packet paid calls and vzeroupper.

// ---------------------------------------------------------------------------------------
// N = 1: the scalar reference.

template <>
struct vbool<1> {
  bool m = false;
  vbool() = default;
  explicit vbool(bool b) : m(b) {}
  friend vbool operator&(vbool a, vbool b) { return vbool(a.m && b.m); }
  friend vbool operator|(vbool a, vbool b) { return vbool(a.m || b.m); }
  friend vbool operator^(vbool a, vbool b) { return vbool(a.m != b.m); }
  friend vbool operator!(vbool a) { return vbool(!a.m); }
  vbool& operator&=(vbool b) { return *this = *this & b; }
  vbool& operator|=(vbool b) { return *this = *this | b; }
  [[nodiscard]] bool lane(int) const { return m; }
  static vbool from_bits(unsigned bits) { return vbool((bits & 1u) != 0); }
};

template <>
struct vfloat<1> {
  float v = 0.0f;
  vfloat() = default;
  vfloat(float f) : v(f) {}  // NOLINT: broadcasting is the point
  static vfloat load(const float* p) { return vfloat(*p); }
  void store(float* p) const { *p = v; }
  [[nodiscard]] float lane(int) const { return v; }
  void set_lane(int, float f) { v = f; }
  friend vfloat operator+(vfloat a, vfloat b) { return a.v + b.v; }
  friend vfloat operator-(vfloat a, vfloat b) { return a.v - b.v; }
  friend vfloat operator*(vfloat a, vfloat b) { return a.v * b.v; }
  friend vfloat operator/(vfloat a, vfloat b) { return a.v / b.v; }
  friend vfloat operator-(vfloat a) { return -a.v; }
  friend vbool<1> operator<(vfloat a, vfloat b) { return vbool<1>(a.v < b.v); }
  friend vbool<1> operator<=(vfloat a, vfloat b) { return vbool<1>(a.v <= b.v); }
  friend vbool<1> operator>(vfloat a, vfloat b) { return vbool<1>(a.v > b.v); }
  friend vbool<1> operator>=(vfloat a, vfloat b) { return vbool<1>(a.v >= b.v); }
  friend vbool<1> operator==(vfloat a, vfloat b) { return vbool<1>(a.v == b.v); }
};

template <>
struct vint<1> {
  std::int32_t v = 0;
  vint() = default;
  vint(std::int32_t i) : v(i) {}  // NOLINT: broadcasting is the point
  [[nodiscard]] std::int32_t lane(int) const { return v; }
  void set_lane(int, std::int32_t i) { v = i; }
  void store(std::int32_t* p) const { *p = v; }
  friend vbool<1> operator<(vint a, vint b) { return vbool<1>(a.v < b.v); }
  friend vbool<1> operator>(vint a, vint b) { return vbool<1>(a.v > b.v); }
  friend vbool<1> operator==(vint a, vint b) { return vbool<1>(a.v == b.v); }
};

inline vfloat<1> min(vfloat<1> a, vfloat<1> b) { return a.v < b.v ? a : b; }
inline vfloat<1> max(vfloat<1> a, vfloat<1> b) { return a.v > b.v ? a : b; }
/// The least and greatest lane (for finite lanes; with NaN lanes the result is unspecified).
inline float reduce_min(vfloat<1> a) { return a.v; }
inline float reduce_max(vfloat<1> a) { return a.v; }
inline vfloat<1> select(vbool<1> m, vfloat<1> a, vfloat<1> b) { return m.m ? a : b; }
inline vint<1> select(vbool<1> m, vint<1> a, vint<1> b) { return m.m ? a : b; }
inline bool any(vbool<1> m) { return m.m; }
inline bool all(vbool<1> m) { return m.m; }
inline bool none(vbool<1> m) { return !m.m; }
inline unsigned bits(vbool<1> m) { return m.m ? 1u : 0u; }
/// Sign bit set (true for -0.0 and negative values, also for NaN with the sign bit).
inline vbool<1> sign_bit(vfloat<1> a) {
  std::uint32_t u;
  std::memcpy(&u, &a.v, 4);
  return vbool<1>((u >> 31) != 0);
}

// ---------------------------------------------------------------------------------------
// N = 4: SSE.

template <>
struct vbool<4> {
  __m128 m;
  vbool() = default;
  explicit vbool(__m128 x) : m(x) {}
  explicit vbool(bool b) : m(_mm_castsi128_ps(_mm_set1_epi32(b ? -1 : 0))) {}
  friend vbool operator&(vbool a, vbool b) { return vbool(_mm_and_ps(a.m, b.m)); }
  friend vbool operator|(vbool a, vbool b) { return vbool(_mm_or_ps(a.m, b.m)); }
  friend vbool operator^(vbool a, vbool b) { return vbool(_mm_xor_ps(a.m, b.m)); }
  friend vbool operator!(vbool a) {
    return vbool(_mm_xor_ps(a.m, _mm_castsi128_ps(_mm_set1_epi32(-1))));
  }
  vbool& operator&=(vbool b) { return *this = *this & b; }
  vbool& operator|=(vbool b) { return *this = *this | b; }
  [[nodiscard]] bool lane(int i) const { return ((_mm_movemask_ps(m) >> i) & 1) != 0; }
  static vbool from_bits(unsigned b) {
    return vbool(_mm_castsi128_ps(_mm_setr_epi32((b & 1u) ? -1 : 0, (b & 2u) ? -1 : 0,
                                                 (b & 4u) ? -1 : 0, (b & 8u) ? -1 : 0)));
  }
};

template <>
struct vfloat<4> {
  __m128 v;
  vfloat() = default;
  vfloat(float f) : v(_mm_set1_ps(f)) {}  // NOLINT: broadcasting is the point
  explicit vfloat(__m128 x) : v(x) {}
  static vfloat load(const float* p) { return vfloat(_mm_loadu_ps(p)); }
  void store(float* p) const { _mm_storeu_ps(p, v); }
  [[nodiscard]] float lane(int i) const {
    alignas(16) float tmp[4];
    _mm_store_ps(tmp, v);
    return tmp[i];
  }
  void set_lane(int i, float f) {
    alignas(16) float tmp[4];
    _mm_store_ps(tmp, v);
    tmp[i] = f;
    v = _mm_load_ps(tmp);
  }
  friend vfloat operator+(vfloat a, vfloat b) { return vfloat(_mm_add_ps(a.v, b.v)); }
  friend vfloat operator-(vfloat a, vfloat b) { return vfloat(_mm_sub_ps(a.v, b.v)); }
  friend vfloat operator*(vfloat a, vfloat b) { return vfloat(_mm_mul_ps(a.v, b.v)); }
  friend vfloat operator/(vfloat a, vfloat b) { return vfloat(_mm_div_ps(a.v, b.v)); }
  friend vfloat operator-(vfloat a) { return vfloat(_mm_xor_ps(a.v, _mm_set1_ps(-0.0f))); }
  friend vbool<4> operator<(vfloat a, vfloat b) { return vbool<4>(_mm_cmplt_ps(a.v, b.v)); }
  friend vbool<4> operator<=(vfloat a, vfloat b) { return vbool<4>(_mm_cmple_ps(a.v, b.v)); }
  friend vbool<4> operator>(vfloat a, vfloat b) { return vbool<4>(_mm_cmpgt_ps(a.v, b.v)); }
  friend vbool<4> operator>=(vfloat a, vfloat b) { return vbool<4>(_mm_cmpge_ps(a.v, b.v)); }
  friend vbool<4> operator==(vfloat a, vfloat b) { return vbool<4>(_mm_cmpeq_ps(a.v, b.v)); }
};

template <>
struct vint<4> {
  __m128i v;
  vint() = default;
  vint(std::int32_t i) : v(_mm_set1_epi32(i)) {}  // NOLINT: broadcasting is the point
  explicit vint(__m128i x) : v(x) {}
  void store(std::int32_t* p) const { _mm_storeu_si128(reinterpret_cast<__m128i*>(p), v); }
  [[nodiscard]] std::int32_t lane(int i) const {
    alignas(16) std::int32_t tmp[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(tmp), v);
    return tmp[i];
  }
  void set_lane(int i, std::int32_t x) {
    alignas(16) std::int32_t tmp[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(tmp), v);
    tmp[i] = x;
    v = _mm_load_si128(reinterpret_cast<const __m128i*>(tmp));
  }
  friend vbool<4> operator<(vint a, vint b) {
    return vbool<4>(_mm_castsi128_ps(_mm_cmplt_epi32(a.v, b.v)));
  }
  friend vbool<4> operator>(vint a, vint b) {
    return vbool<4>(_mm_castsi128_ps(_mm_cmpgt_epi32(a.v, b.v)));
  }
  friend vbool<4> operator==(vint a, vint b) {
    return vbool<4>(_mm_castsi128_ps(_mm_cmpeq_epi32(a.v, b.v)));
  }
};

// minps/maxps: the second operand when either is NaN; the N = 1 versions match.
inline vfloat<4> min(vfloat<4> a, vfloat<4> b) { return vfloat<4>(_mm_min_ps(a.v, b.v)); }
inline vfloat<4> max(vfloat<4> a, vfloat<4> b) { return vfloat<4>(_mm_max_ps(a.v, b.v)); }
/// `op` (min or max) over the lanes: pairs of halves, then of neighbours.
template <class Op>
inline float reduce_lanes(vfloat<4> a, Op op) {
  const vfloat<4> t = op(a, vfloat<4>(_mm_shuffle_ps(a.v, a.v, _MM_SHUFFLE(1, 0, 3, 2))));
  return _mm_cvtss_f32(op(t, vfloat<4>(_mm_shuffle_ps(t.v, t.v, _MM_SHUFFLE(2, 3, 0, 1)))).v);
}
inline float reduce_min(vfloat<4> a) { return reduce_lanes(a, [](vfloat<4> x, vfloat<4> y) { return min(x, y); }); }
inline float reduce_max(vfloat<4> a) { return reduce_lanes(a, [](vfloat<4> x, vfloat<4> y) { return max(x, y); }); }
inline vfloat<4> select(vbool<4> m, vfloat<4> a, vfloat<4> b) {
  return vfloat<4>(_mm_blendv_ps(b.v, a.v, m.m));
}
inline vint<4> select(vbool<4> m, vint<4> a, vint<4> b) {
  return vint<4>(_mm_castps_si128(
      _mm_blendv_ps(_mm_castsi128_ps(b.v), _mm_castsi128_ps(a.v), m.m)));
}
inline unsigned bits(vbool<4> m) { return static_cast<unsigned>(_mm_movemask_ps(m.m)); }
inline bool any(vbool<4> m) { return bits(m) != 0; }
inline bool all(vbool<4> m) { return bits(m) == 0xFu; }
inline bool none(vbool<4> m) { return bits(m) == 0; }
inline vbool<4> sign_bit(vfloat<4> a) {
  return vbool<4>(_mm_castsi128_ps(_mm_srai_epi32(_mm_castps_si128(a.v), 31)));
}

// GCC does not give friend functions defined in a class the target of the enclosing
// `#pragma GCC target`; the wide types' operators name it themselves.
#define RTC_ISA_FRIEND friend __attribute__((target(RTC_ISA_TARGET)))

#if RTC_ISA_WIDTH >= 8
// ---------------------------------------------------------------------------------------
// N = 8: AVX2.

template <>
struct vbool<8> {
  __m256 m;
  vbool() = default;
  explicit vbool(__m256 x) : m(x) {}
  explicit vbool(bool b) : m(_mm256_castsi256_ps(_mm256_set1_epi32(b ? -1 : 0))) {}
  RTC_ISA_FRIEND vbool operator&(vbool a, vbool b) { return vbool(_mm256_and_ps(a.m, b.m)); }
  RTC_ISA_FRIEND vbool operator|(vbool a, vbool b) { return vbool(_mm256_or_ps(a.m, b.m)); }
  RTC_ISA_FRIEND vbool operator^(vbool a, vbool b) { return vbool(_mm256_xor_ps(a.m, b.m)); }
  RTC_ISA_FRIEND vbool operator!(vbool a) {
    return vbool(_mm256_xor_ps(a.m, _mm256_castsi256_ps(_mm256_set1_epi32(-1))));
  }
  vbool& operator&=(vbool b) { return *this = *this & b; }
  vbool& operator|=(vbool b) { return *this = *this | b; }
  [[nodiscard]] bool lane(int i) const { return ((_mm256_movemask_ps(m) >> i) & 1) != 0; }
  static vbool from_bits(unsigned b) {
    const __m256i lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    const __m256i x = _mm256_and_si256(_mm256_set1_epi32(static_cast<int>(b)), lane_bit);
    return vbool(_mm256_castsi256_ps(_mm256_cmpeq_epi32(x, lane_bit)));
  }
};

template <>
struct vfloat<8> {
  __m256 v;
  vfloat() = default;
  vfloat(float f) : v(_mm256_set1_ps(f)) {}  // NOLINT: broadcasting is the point
  explicit vfloat(__m256 x) : v(x) {}
  static vfloat load(const float* p) { return vfloat(_mm256_loadu_ps(p)); }
  void store(float* p) const { _mm256_storeu_ps(p, v); }
  [[nodiscard]] float lane(int i) const {
    alignas(32) float tmp[8];
    _mm256_store_ps(tmp, v);
    return tmp[i];
  }
  void set_lane(int i, float f) {
    alignas(32) float tmp[8];
    _mm256_store_ps(tmp, v);
    tmp[i] = f;
    v = _mm256_load_ps(tmp);
  }
  RTC_ISA_FRIEND vfloat operator+(vfloat a, vfloat b) { return vfloat(_mm256_add_ps(a.v, b.v)); }
  RTC_ISA_FRIEND vfloat operator-(vfloat a, vfloat b) { return vfloat(_mm256_sub_ps(a.v, b.v)); }
  RTC_ISA_FRIEND vfloat operator*(vfloat a, vfloat b) { return vfloat(_mm256_mul_ps(a.v, b.v)); }
  RTC_ISA_FRIEND vfloat operator/(vfloat a, vfloat b) { return vfloat(_mm256_div_ps(a.v, b.v)); }
  RTC_ISA_FRIEND vfloat operator-(vfloat a) { return vfloat(_mm256_xor_ps(a.v, _mm256_set1_ps(-0.0f))); }
  RTC_ISA_FRIEND vbool<8> operator<(vfloat a, vfloat b) { return vbool<8>(_mm256_cmp_ps(a.v, b.v, _CMP_LT_OS)); }
  RTC_ISA_FRIEND vbool<8> operator<=(vfloat a, vfloat b) { return vbool<8>(_mm256_cmp_ps(a.v, b.v, _CMP_LE_OS)); }
  RTC_ISA_FRIEND vbool<8> operator>(vfloat a, vfloat b) { return vbool<8>(_mm256_cmp_ps(a.v, b.v, _CMP_GT_OS)); }
  RTC_ISA_FRIEND vbool<8> operator>=(vfloat a, vfloat b) { return vbool<8>(_mm256_cmp_ps(a.v, b.v, _CMP_GE_OS)); }
  RTC_ISA_FRIEND vbool<8> operator==(vfloat a, vfloat b) { return vbool<8>(_mm256_cmp_ps(a.v, b.v, _CMP_EQ_OQ)); }
};

template <>
struct vint<8> {
  __m256i v;
  vint() = default;
  vint(std::int32_t i) : v(_mm256_set1_epi32(i)) {}  // NOLINT: broadcasting is the point
  explicit vint(__m256i x) : v(x) {}
  static vint load(const std::int32_t* p) { return vint(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(p))); }
  void store(std::int32_t* p) const { _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), v); }
  [[nodiscard]] std::int32_t lane(int i) const {
    alignas(32) std::int32_t tmp[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(tmp), v);
    return tmp[i];
  }
  void set_lane(int i, std::int32_t x) {
    alignas(32) std::int32_t tmp[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(tmp), v);
    tmp[i] = x;
    v = _mm256_load_si256(reinterpret_cast<const __m256i*>(tmp));
  }
  RTC_ISA_FRIEND vbool<8> operator<(vint a, vint b) { return vbool<8>(_mm256_castsi256_ps(_mm256_cmpgt_epi32(b.v, a.v))); }
  RTC_ISA_FRIEND vbool<8> operator>(vint a, vint b) { return vbool<8>(_mm256_castsi256_ps(_mm256_cmpgt_epi32(a.v, b.v))); }
  RTC_ISA_FRIEND vbool<8> operator==(vint a, vint b) {
    return vbool<8>(_mm256_castsi256_ps(_mm256_cmpeq_epi32(a.v, b.v)));
  }
};

inline vfloat<8> min(vfloat<8> a, vfloat<8> b) { return vfloat<8>(_mm256_min_ps(a.v, b.v)); }
inline vfloat<8> max(vfloat<8> a, vfloat<8> b) { return vfloat<8>(_mm256_max_ps(a.v, b.v)); }
inline float reduce_min(vfloat<8> a) {
  return reduce_min(vfloat<4>(_mm_min_ps(_mm256_castps256_ps128(a.v), _mm256_extractf128_ps(a.v, 1))));
}
inline float reduce_max(vfloat<8> a) {
  return reduce_max(vfloat<4>(_mm_max_ps(_mm256_castps256_ps128(a.v), _mm256_extractf128_ps(a.v, 1))));
}
inline vfloat<8> select(vbool<8> m, vfloat<8> a, vfloat<8> b) {
  return vfloat<8>(_mm256_blendv_ps(b.v, a.v, m.m));
}
inline vint<8> select(vbool<8> m, vint<8> a, vint<8> b) {
  return vint<8>(_mm256_castps_si256(
      _mm256_blendv_ps(_mm256_castsi256_ps(b.v), _mm256_castsi256_ps(a.v), m.m)));
}
inline unsigned bits(vbool<8> m) { return static_cast<unsigned>(_mm256_movemask_ps(m.m)); }
inline bool any(vbool<8> m) { return bits(m) != 0; }
inline bool all(vbool<8> m) { return bits(m) == 0xFFu; }
inline bool none(vbool<8> m) { return _mm256_testz_ps(m.m, m.m) != 0; }
inline vbool<8> sign_bit(vfloat<8> a) {
  return vbool<8>(_mm256_castsi256_ps(_mm256_srai_epi32(_mm256_castps_si256(a.v), 31)));
}
#endif  // RTC_ISA_WIDTH >= 8

#if RTC_ISA_WIDTH >= 16
// ---------------------------------------------------------------------------------------
// N = 16: AVX-512 (F, DQ, BW, VL), with mask registers for vbool.

template <>
struct vbool<16> {
  __mmask16 m;
  vbool() = default;
  explicit vbool(__mmask16 x) : m(x) {}
  explicit vbool(bool b) : m(b ? static_cast<__mmask16>(0xFFFF) : static_cast<__mmask16>(0)) {}
  RTC_ISA_FRIEND vbool operator&(vbool a, vbool b) { return vbool(static_cast<__mmask16>(a.m & b.m)); }
  RTC_ISA_FRIEND vbool operator|(vbool a, vbool b) { return vbool(static_cast<__mmask16>(a.m | b.m)); }
  RTC_ISA_FRIEND vbool operator^(vbool a, vbool b) { return vbool(static_cast<__mmask16>(a.m ^ b.m)); }
  RTC_ISA_FRIEND vbool operator!(vbool a) { return vbool(static_cast<__mmask16>(~a.m)); }
  vbool& operator&=(vbool b) { return *this = *this & b; }
  vbool& operator|=(vbool b) { return *this = *this | b; }
  [[nodiscard]] bool lane(int i) const { return ((m >> i) & 1u) != 0; }
  static vbool from_bits(unsigned b) { return vbool(static_cast<__mmask16>(b & 0xFFFFu)); }
};

template <>
struct vfloat<16> {
  __m512 v;
  vfloat() = default;
  vfloat(float f) : v(_mm512_set1_ps(f)) {}  // NOLINT: broadcasting is the point
  explicit vfloat(__m512 x) : v(x) {}
  static vfloat load(const float* p) { return vfloat(_mm512_loadu_ps(p)); }
  void store(float* p) const { _mm512_storeu_ps(p, v); }
  [[nodiscard]] float lane(int i) const {
    alignas(64) float tmp[16];
    _mm512_store_ps(tmp, v);
    return tmp[i];
  }
  void set_lane(int i, float f) {
    v = _mm512_mask_broadcastss_ps(v, static_cast<__mmask16>(1u << i), _mm_set_ss(f));
  }
  RTC_ISA_FRIEND vfloat operator+(vfloat a, vfloat b) { return vfloat(_mm512_add_ps(a.v, b.v)); }
  RTC_ISA_FRIEND vfloat operator-(vfloat a, vfloat b) { return vfloat(_mm512_sub_ps(a.v, b.v)); }
  RTC_ISA_FRIEND vfloat operator*(vfloat a, vfloat b) { return vfloat(_mm512_mul_ps(a.v, b.v)); }
  RTC_ISA_FRIEND vfloat operator/(vfloat a, vfloat b) { return vfloat(_mm512_div_ps(a.v, b.v)); }
  RTC_ISA_FRIEND vfloat operator-(vfloat a) {
    return vfloat(_mm512_castsi512_ps(
        _mm512_xor_si512(_mm512_castps_si512(a.v), _mm512_set1_epi32(static_cast<int>(0x80000000u)))));
  }
  RTC_ISA_FRIEND vbool<16> operator<(vfloat a, vfloat b) { return vbool<16>(_mm512_cmp_ps_mask(a.v, b.v, _CMP_LT_OS)); }
  RTC_ISA_FRIEND vbool<16> operator<=(vfloat a, vfloat b) { return vbool<16>(_mm512_cmp_ps_mask(a.v, b.v, _CMP_LE_OS)); }
  RTC_ISA_FRIEND vbool<16> operator>(vfloat a, vfloat b) { return vbool<16>(_mm512_cmp_ps_mask(a.v, b.v, _CMP_GT_OS)); }
  RTC_ISA_FRIEND vbool<16> operator>=(vfloat a, vfloat b) { return vbool<16>(_mm512_cmp_ps_mask(a.v, b.v, _CMP_GE_OS)); }
  RTC_ISA_FRIEND vbool<16> operator==(vfloat a, vfloat b) { return vbool<16>(_mm512_cmp_ps_mask(a.v, b.v, _CMP_EQ_OQ)); }
};

template <>
struct vint<16> {
  __m512i v;
  vint() = default;
  vint(std::int32_t i) : v(_mm512_set1_epi32(i)) {}  // NOLINT: broadcasting is the point
  explicit vint(__m512i x) : v(x) {}
  static vint load(const std::int32_t* p) { return vint(_mm512_loadu_si512(p)); }
  void store(std::int32_t* p) const { _mm512_storeu_si512(p, v); }
  [[nodiscard]] std::int32_t lane(int i) const {
    alignas(64) std::int32_t tmp[16];
    _mm512_store_si512(tmp, v);
    return tmp[i];
  }
  void set_lane(int i, std::int32_t x) { v = _mm512_mask_set1_epi32(v, static_cast<__mmask16>(1u << i), x); }
  RTC_ISA_FRIEND vbool<16> operator<(vint a, vint b) { return vbool<16>(_mm512_cmplt_epi32_mask(a.v, b.v)); }
  RTC_ISA_FRIEND vbool<16> operator>(vint a, vint b) { return vbool<16>(_mm512_cmpgt_epi32_mask(a.v, b.v)); }
  RTC_ISA_FRIEND vbool<16> operator==(vint a, vint b) { return vbool<16>(_mm512_cmpeq_epi32_mask(a.v, b.v)); }
};

// The zero-masking forms: GCC 12's _mm512_min_ps/_mm512_max_ps read an uninitialised
// placeholder that trips -Wuninitialized. Same instruction, same NaN rule.
inline vfloat<16> min(vfloat<16> a, vfloat<16> b) { return vfloat<16>(_mm512_maskz_min_ps(0xFFFF, a.v, b.v)); }
inline vfloat<16> max(vfloat<16> a, vfloat<16> b) { return vfloat<16>(_mm512_maskz_max_ps(0xFFFF, a.v, b.v)); }
// Within the 512-bit register, in the zero-masking forms (as above: the plain shuffles and the
// 256-bit casts read an uninitialised placeholder that trips GCC 12).
template <class Op>
inline float reduce_lanes(vfloat<16> a, Op op) {
  vfloat<16> t = op(a, vfloat<16>(_mm512_maskz_shuffle_f32x4(0xFFFF, a.v, a.v, _MM_SHUFFLE(1, 0, 3, 2))));
  t = op(t, vfloat<16>(_mm512_maskz_shuffle_f32x4(0xFFFF, t.v, t.v, _MM_SHUFFLE(2, 3, 0, 1))));
  t = op(t, vfloat<16>(_mm512_maskz_permute_ps(0xFFFF, t.v, _MM_SHUFFLE(1, 0, 3, 2))));
  t = op(t, vfloat<16>(_mm512_maskz_permute_ps(0xFFFF, t.v, _MM_SHUFFLE(2, 3, 0, 1))));
  return _mm512_cvtss_f32(t.v);
}
inline float reduce_min(vfloat<16> a) {
  return reduce_lanes(a, [](vfloat<16> x, vfloat<16> y) { return min(x, y); });
}
inline float reduce_max(vfloat<16> a) {
  return reduce_lanes(a, [](vfloat<16> x, vfloat<16> y) { return max(x, y); });
}
inline vfloat<16> select(vbool<16> m, vfloat<16> a, vfloat<16> b) {
  return vfloat<16>(_mm512_mask_blend_ps(m.m, b.v, a.v));
}
inline vint<16> select(vbool<16> m, vint<16> a, vint<16> b) {
  return vint<16>(_mm512_mask_blend_epi32(m.m, b.v, a.v));
}
inline unsigned bits(vbool<16> m) { return static_cast<unsigned>(m.m); }
inline bool any(vbool<16> m) { return m.m != 0; }
inline bool all(vbool<16> m) { return m.m == 0xFFFFu; }
inline bool none(vbool<16> m) { return m.m == 0; }
inline vbool<16> sign_bit(vfloat<16> a) { return vbool<16>(_mm512_movepi32_mask(_mm512_castps_si512(a.v))); }
#endif  // RTC_ISA_WIDTH >= 16

/// Three packet floats: a vector per lane, stored as structure of arrays and indexed by axis
/// (the triangle test picks axes at run time).
template <int N>
struct PacketVec3 {
  vfloat<N> v[3];
  [[nodiscard]] const vfloat<N>& operator[](int axis) const { return v[axis]; }
  [[nodiscard]] vfloat<N>& operator[](int axis) { return v[axis]; }
};

}  // namespace rtc::RTC_ISA_NS
RTC_ISA_END
