// Deterministic elementary functions: range reduction with exact frexp/ldexp/floor and
// fixed-order polynomial evaluation in double.
#include "common/math/det_math.h"

#include <cmath>
#include <limits>

namespace rtc {

double det_exp2(double y) {
  if (std::isnan(y)) return y;
  if (y > 1024.0) return std::numeric_limits<double>::infinity();
  if (y < -1075.0) return 0.0;
  const double k = std::floor(y);
  const double r = (y - k) * 0.69314718055994530942;  // in [0, ln 2)
  // Taylor series of e^r to r^17/17!: remainder below 2e-17 for r < ln 2.
  double term = 1.0, sum = 1.0;
  for (int n = 1; n <= 17; ++n) {
    term = term * r / static_cast<double>(n);
    sum = sum + term;
  }
  return std::ldexp(sum, static_cast<int>(k));
}

double det_log2(double x) {
  if (std::isnan(x) || x < 0.0) return std::numeric_limits<double>::quiet_NaN();
  if (x == 0.0) return -std::numeric_limits<double>::infinity();
  if (std::isinf(x)) return x;
  int e = 0;
  double m = std::frexp(x, &e);  // x = m 2^e, m in [0.5, 1)
  if (m < 0.70710678118654752440) {
    m = m * 2.0;
    e -= 1;
  }
  // ln m = 2 atanh(s), s = (m - 1) / (m + 1), |s| < 0.1716: odd series to s^27.
  const double s = (m - 1.0) / (m + 1.0);
  const double s2 = s * s;
  double sum = 0.0;
  for (int n = 27; n >= 1; n -= 2) sum = sum * s2 + 1.0 / static_cast<double>(n);
  const double ln_m = 2.0 * s * sum;
  return static_cast<double>(e) + ln_m * 1.44269504088896340736;
}

float det_powf(float x, float e) {
  if (e == 0.0f) return 1.0f;
  if (!(x > 0.0f)) return 0.0f;
  if (x >= 1.0f) return 1.0f;
  const double y = static_cast<double>(e) * det_log2(static_cast<double>(x));
  if (y < -160.0) return 0.0f;  // below the smallest float
  return static_cast<float>(det_exp2(y));
}

double det_tan(double x) {
  // sin and cos by Taylor series on |x| < pi/2 (terms to x^29: remainder below 1e-17).
  const double x2 = x * x;
  double s = 0.0, c = 0.0;
  for (int n = 29; n >= 3; n -= 2) s = (s + 1.0) * (-x2 / (static_cast<double>(n) * static_cast<double>(n - 1)));
  s = x * (1.0 + s);
  for (int n = 28; n >= 2; n -= 2) c = (c + 1.0) * (-x2 / (static_cast<double>(n) * static_cast<double>(n - 1)));
  c = 1.0 + c;
  return s / c;
}

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoOverPi = 6.36619772367581382433e-01;

// pi/2 in pieces of 33 significant bits (fdlibm's pio2_1, pio2_2, pio2_3), so k * piece is
// exact for |k| < 2^20, and the tails of the last two (pio2_2t, pio2_3t).
constexpr double kPio2Piece1 = 0x1.921fb544p+0;
constexpr double kPio2Piece2 = 0x1.0b4611a6p-34;
constexpr double kPio2Tail2 = 0x1.3198a2e037073p-69;
constexpr double kPio2Piece3 = 0x1.3198a2ep-69;
constexpr double kPio2Tail3 = 0x1.b839a252049c1p-104;
// Below this |x| the quotient k = round(x 2/pi) stays under 2^19 (fdlibm's "medium" range).
constexpr double kMediumLimit = 0x1p19 * 1.57079632679489661923;

/// Writes x - k pi/2 as hi + lo (|hi| <= pi/4 + 1 ulp, lo below half an ulp of hi) and returns
/// k mod 4. fdlibm's __ieee754_rem_pio2 medium path with all three steps always taken: each
/// step subtracts k times the next 33 bits of pi/2 and carries the rounding error in `w`
/// (about 118 correct bits, enough for every double near a multiple of pi/2 below 2^19).
int reduce_pio2(double x, double& hi, double& lo) {
  const double ax = std::abs(x);
  const double k = std::floor(ax * kTwoOverPi + 0.5);
  double r = ax - k * kPio2Piece1;  // exact: k * piece is exact, and r is near ax (Sterbenz)
  double w = k * kPio2Piece2;
  double t = r;
  r = t - w;
  w = k * kPio2Tail2 - ((t - r) - w);
  t = r;
  w = k * kPio2Piece3;
  r = t - w;
  w = k * kPio2Tail3 - ((t - r) - w);
  hi = r - w;
  lo = (r - hi) - w;
  int quadrant = static_cast<int>(k - 4.0 * std::floor(k * 0.25));
  if (std::signbit(x)) {
    hi = -hi;
    lo = -lo;
    quadrant = (4 - quadrant) & 3;
  }
  return quadrant;
}

/// sin(r) and cos(r) for |r| <= pi/4 + 1 ulp by Taylor series (sin to r^25, cos to r^24:
/// remainders below 1e-26), with the first-order correction for the tail `lo`.
void sin_cos_kernel(double r, double lo, double& s, double& c) {
  const double r2 = r * r;
  double sum = 0.0;
  for (int n = 25; n >= 3; n -= 2) {
    sum = (sum + 1.0) * (-r2 / (static_cast<double>(n) * static_cast<double>(n - 1)));
  }
  const double sin_r = r + r * sum;
  sum = 0.0;
  for (int n = 24; n >= 2; n -= 2) {
    sum = (sum + 1.0) * (-r2 / (static_cast<double>(n) * static_cast<double>(n - 1)));
  }
  const double cos_r = 1.0 + sum;
  // sin(r + lo) = sin r + lo cos r, cos(r + lo) = cos r - lo sin r (lo^2 is below 2^-100).
  s = sin_r + lo * cos_r;
  c = cos_r - lo * sin_r;
}

/// sin and cos of x through the quadrant of the reduction.
void det_sin_cos(double x, double& s, double& c) {
  if (!std::isfinite(x)) {
    s = c = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  if (x == 0.0) {  // keeps the sign of -0
    s = x;
    c = 1.0;
    return;
  }
  // fmod is exact (the remainder is representable), so this only changes the modulus from
  // 2 pi to the double nearest it: |x| / (2 pi) * 2.4e-16 of absolute error.
  if (std::abs(x) > kMediumLimit) x = std::fmod(x, 2.0 * kPi);
  double hi = 0.0, lo = 0.0;
  const int quadrant = reduce_pio2(x, hi, lo);
  double sr = 0.0, cr = 0.0;
  sin_cos_kernel(hi, lo, sr, cr);
  switch (quadrant) {
    case 0:
      s = sr;
      c = cr;
      break;
    case 1:
      s = cr;
      c = -sr;
      break;
    case 2:
      s = -sr;
      c = -cr;
      break;
    default:
      s = -cr;
      c = sr;
      break;
  }
}

/// atan(z) for z in [0, 1]. Above tan(pi/8), atan z = pi/4 + atan((z - 1) / (z + 1)); the odd
/// Taylor series then runs on |t| <= tan(pi/8) = 0.4142 to t^47 (remainder below 1e-19 t).
double atan_unit(double z) {
  double base = 0.0;
  if (z > 0.41421356237309504880) {
    z = (z - 1.0) / (z + 1.0);
    base = 0.25 * kPi;
  }
  const double z2 = z * z;
  double sum = 0.0;
  for (int n = 47; n >= 3; n -= 2) sum = (sum + 1.0 / static_cast<double>(n)) * -z2;
  return base + (z + z * sum);
}

}  // namespace

double det_sin(double x) {
  double s = 0.0, c = 0.0;
  det_sin_cos(x, s, c);
  return s;
}

double det_cos(double x) {
  double s = 0.0, c = 0.0;
  det_sin_cos(x, s, c);
  return c;
}

double det_atan2(double y, double x) {
  if (std::isnan(x) || std::isnan(y)) return std::numeric_limits<double>::quiet_NaN();
  double ax = std::abs(x), ay = std::abs(y);
  if (std::isinf(ax) && std::isinf(ay)) ax = ay = 1.0;
  double a = 0.0;  // the angle for |x|, |y| in [0, pi/2]
  if (ay == 0.0) {
    a = 0.0;
  } else if (ay <= ax) {
    a = atan_unit(ay / ax);
  } else {
    // pi/2 - atan(x / y): the subtraction loses nothing, the result is at least pi/4.
    a = 0.5 * kPi - atan_unit(ax / ay);
  }
  if (std::signbit(x)) a = kPi - a;
  return std::signbit(y) ? -a : a;
}

double det_acos(double x) {
  if (!(std::abs(x) <= 1.0)) return std::numeric_limits<double>::quiet_NaN();
  // 1 - x and 1 + x are exact near +-1 (Sterbenz), where 1 - x * x would lose the digits.
  return det_atan2(std::sqrt((1.0 - x) * (1.0 + x)), x);
}

}  // namespace rtc
