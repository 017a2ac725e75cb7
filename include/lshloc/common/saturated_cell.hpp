#pragma once
// floor() to a 32-bit cell index that is defined for every double.
// Stateless; safe from any thread.
#include <cmath>
#include <cstdint>

namespace lshloc {

/// floor(v) as an int32, saturated (and NaN as the lowest value): cells of
/// absurd coordinates share the edge cell instead of overflowing the cast.
inline std::int32_t saturated_cell(double v) {
  const double f = std::floor(v);
  if (!(f > -2147483648.0)) return INT32_MIN;
  if (f > 2147483647.0) return INT32_MAX;
  return static_cast<std::int32_t>(f);
}

}  // namespace lshloc
