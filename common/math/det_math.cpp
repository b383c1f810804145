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

}  // namespace rtc
