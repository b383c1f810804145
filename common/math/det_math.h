// Elementary functions built only from IEEE +, -, *, / and exact scaling, so they give the
// same bits on every x86-64 CPU. glibc picks FMA or non-FMA variants of pow, exp, log, tan at
// run time, which may differ in the last bit between workers; pixels must not.
#pragma once

namespace rtc {

/// 2^y, relative error below 1e-15; 0 below 2^-1074, +inf above 2^1024.
[[nodiscard]] double det_exp2(double y);
/// log2(x) for x > 0 (finite), absolute error below 1e-15; -inf for 0, NaN for x < 0.
[[nodiscard]] double det_log2(double x);
/// x^e for the Phong highlight: x in [0, 1], e >= 0 (x <= 0 gives 0 unless e == 0).
[[nodiscard]] float det_powf(float x, float e);
/// tan(x) for |x| < pi/2, relative error below 1e-13 (cos(x) loses digits near pi/2).
[[nodiscard]] double det_tan(double x);

}  // namespace rtc
