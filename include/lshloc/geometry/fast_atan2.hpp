#pragma once
// atan2 without the library call, for the descriptor's per-point loop
// (docs/design.md section 2.1), where libm's atan2 was a large share of a
// mapper's time (docs/results/live-map.md). Within 2e-14 rad of std::atan2
// (tested), far below the float descriptor's resolution (about 1e-7 of a bin).
// Thread safety: a pure function.
#include <cmath>
#include <numbers>

namespace lshloc {

/// atan2(y, x) in [-pi, pi], as std::atan2 up to 2e-14 rad for finite
/// arguments; atan2(+-0, +0) = +-0 and atan2(+-0, -0) = +-pi as there.
inline double fast_atan2(double y, double x) {
  constexpr double kPi = std::numbers::pi;
  constexpr double kTanPi8 = 0.41421356237309503;  // tan(pi / 8)
  const double ax = std::abs(x), ay = std::abs(y);
  // Reduce to atan(t), |t| <= tan(pi / 8): atan(ay / ax) directly, as
  // pi/2 - atan(ax / ay), or as pi/4 + atan((ay - ax) / (ay + ax)). Selects,
  // not branches: the octant is random from one point to the next.
  const bool steep = ay * kTanPi8 > ax, middle = !steep && ay > kTanPi8 * ax;
  const double num = steep ? -ax : (middle ? ay - ax : ay);
  const double den = steep ? ay : (middle ? ay + ax : ax);
  const double base = steep ? 0.5 * kPi : (middle ? 0.25 * kPi : 0.0);
  const double t = num / (den > 0.0 ? den : 1.0);  // den = 0 only at x = y = 0, where num = 0
  const double s = t * t;
  // A least-squares Chebyshev fit of (atan(t) - t) / t^3 in s = t^2 on [0, tan^2(pi / 8)].
  double p = 0.03067389159909376;
  p = p * s - 0.05880250417098253;
  p = p * s + 0.07566900525168437;
  p = p * s - 0.09079126402284216;
  p = p * s + 0.1111046978694848;
  p = p * s - 0.14285695470768298;
  p = p * s + 0.19999999748421432;
  p = p * s - 0.33333333332339254;
  const double a = base + (t + t * s * p);  // in [0, pi/2]
  const double left = std::signbit(x) ? 1.0 : 0.0;
  return std::copysign(left * kPi + (1.0 - 2.0 * left) * a, y);  // pi - a for x < 0
}

}  // namespace lshloc
