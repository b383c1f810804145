// Elementary functions built only from IEEE +, -, *, /, sqrt (correctly rounded) and exact
// operations (frexp, ldexp, floor, fmod), so they give the same bits on every x86-64 CPU. glibc
// picks FMA or non-FMA variants of pow, exp, log, sin, cos, tan, acos, atan2 at run time, which
// may differ in the last bit between workers; pixels must not.
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

/// sin(x), relative error below 1e-15 for |x| <= 2^19 pi/2 (about 8.2e5; the reduction by pi/2
/// is carried to about 118 bits there, so results near the zeros keep their digits). Larger
/// finite |x| are first reduced exactly modulo the double nearest 2 pi: absolute error below
/// |x| 2^-50. NaN for NaN and infinities.
[[nodiscard]] double det_sin(double x);
/// cos(x), as det_sin.
[[nodiscard]] double det_cos(double x);
/// atan2(y, x) in [-pi, pi], relative error below 1e-15; signed zeros and infinities as libm
/// (atan2(+-0, -0) = +-pi, atan2(+-inf, +-inf) = +-pi/4 or +-3pi/4); NaN in, NaN out.
[[nodiscard]] double det_atan2(double y, double x);
/// acos(x) in [0, pi] for x in [-1, 1] (NaN outside), as atan2(sqrt((1 - x)(1 + x)), x):
/// relative error below 1e-15, also near x = +-1 where the acos series is ill-conditioned.
[[nodiscard]] double det_acos(double x);

}  // namespace rtc
