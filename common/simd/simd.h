// SIMD vocabulary for packet kernels: vfloat<N>, vint<N>, vbool<N>.
// N = 1 is the scalar reference; N = 4 is SSE. Every operation has one meaning at every
// width (min/max return the second operand when either is NaN, exactly like minps/maxps),
// so a kernel written once over N gives the same bits at each width.
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
  __m128 m = _mm_setzero_ps();
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
  __m128 v = _mm_setzero_ps();
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
  __m128i v = _mm_setzero_si128();
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
