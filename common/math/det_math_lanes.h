// det_powf (common/math/det_math.h) for eight lanes at a time, in vectors of doubles: the same
// operations in the same order per lane, so every lane gets det_powf's bits. The Phong
// highlight's power was a tenth of a frame's profile on spd-gears, mostly det_exp2's 17
// dependent double divisions; over a packet's lanes they run side by side.
// Included only by kernel sources compiled per ISA (like common/simd/simd.h), so that each ISA's
// copy is built with its own vector width.
#pragma once

#ifndef RTC_ISA_NS
#error "common/math/det_math_lanes.h is for kernel sources compiled per ISA (rtc_isa_kernels)"
#endif

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "common/math/det_math.h"
#include "common/simd/isa_region.h"

RTC_ISA_BEGIN
namespace rtc::RTC_ISA_NS {

namespace det_lanes {

using v8d = double __attribute__((vector_size(64)));
using v8l = std::int64_t __attribute__((vector_size(64)));
using v8f = float __attribute__((vector_size(32)));

inline v8l bits_of(v8d v) {
  v8l b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}
inline v8d from_bits(v8l b) {
  v8d v;
  std::memcpy(&v, &b, sizeof v);
  return v;
}

/// det_powf for 8 lanes whose x is in (0, 1) and e is positive and finite (the caller sends the
/// others to det_powf itself). Mirrors det_log2, det_exp2 and det_powf step by step.
inline v8f powf8(v8f xf, v8f ef) {
  const v8d x = __builtin_convertvector(xf, v8d);
  // frexp for a normal positive double (every float is one as a double): x = m 2^e, m in [0.5, 1).
  const v8l xb = bits_of(x);
  v8d e = __builtin_convertvector(((xb >> 52) & 0x7FF) - 1022, v8d);
  v8d m = from_bits((xb & ~(std::int64_t{0x7FF} << 52)) | (std::int64_t{1022} << 52));
  const v8l low = m < 0.70710678118654752440;
  m = low ? m * 2.0 : m;
  e = low ? e - 1.0 : e;  // e is a small integer: exact
  // ln m = 2 atanh(s), s = (m - 1) / (m + 1): the series of det_log2, in its order.
  const v8d s = (m - 1.0) / (m + 1.0);
  const v8d s2 = s * s;
  v8d sum{};
  for (int n = 27; n >= 1; n -= 2) sum = sum * s2 + 1.0 / static_cast<double>(n);
  const v8d ln_m = 2.0 * s * sum;
  const v8d log2 = e + ln_m * 1.44269504088896340736;
  const v8d y = __builtin_convertvector(ef, v8d) * log2;
  const v8l tiny = y < -160.0;
  // det_exp2 for y in [-160, 0]: k = floor(y) (round to nearest by the 2^52 + 2^51 trick, exact
  // for |y| < 2^51, then one down where that went up), r = (y - k) ln 2, e^r by its series.
  const v8d zero{};  // +0 in every lane (det_powf returns +0.0f for those)
  const v8d yc = tiny ? zero : y;  // keeps the lanes that return 0 in range
  v8d k = (yc + 6755399441055744.0) - 6755399441055744.0;
  k = k > yc ? k - 1.0 : k;
  const v8d r = (yc - k) * 0.69314718055994530942;
  v8d term = v8d{} + 1.0, series = term;
  for (int n = 1; n <= 17; ++n) {
    term = term * r / static_cast<double>(n);
    series = series + term;
  }
  // ldexp(series, k): k in [-161, 0] and series in [1, 2], so the product is a normal double
  // and multiplying by 2^k is exact.
  const v8l kb = __builtin_convertvector(k, v8l);
  const v8d scale = from_bits((kb + 1023) << 52);
  const v8d result = tiny ? zero : series * scale;
  return __builtin_convertvector(result, v8f);
}

}  // namespace det_lanes

/// out[i] = det_powf(x[i], e[i]) for i < count, with identical bits.
inline void det_powf_lanes(const float* x, const float* e, float* out, std::size_t count) {
  for (std::size_t first = 0; first < count; first += 8) {
    const std::size_t n = count - first < 8 ? count - first : 8;
    det_lanes::v8f xs, es;
    bool general = true;
    for (std::size_t i = 0; i < 8; ++i) {
      const float xi = i < n ? x[first + i] : 0.5f;
      const float ei = i < n ? e[first + i] : 1.0f;
      // Outside x in (0, 1), e in (0, inf): det_powf's early returns (or a NaN), taken there.
      if (!(xi > 0.0f && xi < 1.0f && ei > 0.0f && ei <= 3.4028234663852886e38f)) general = false;
      xs[i] = xi;
      es[i] = ei;
    }
    if (!general) {
      for (std::size_t i = 0; i < n; ++i) out[first + i] = det_powf(x[first + i], e[first + i]);
      continue;
    }
    const det_lanes::v8f p = det_lanes::powf8(xs, es);
    for (std::size_t i = 0; i < n; ++i) out[first + i] = p[i];
  }
}

}  // namespace rtc::RTC_ISA_NS
RTC_ISA_END
