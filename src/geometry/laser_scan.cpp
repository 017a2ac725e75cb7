#include "lshloc/geometry/laser_scan.hpp"

#include <cmath>

#include <bit>
#include <numbers>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc {

std::vector<Point2> LaserScan::endpoints(double min_range, double max_use_range) const {
  std::vector<Point2> out;
  endpoints(out, min_range, max_use_range);
  return out;
}

void LaserScan::endpoints(std::vector<Point2>& out, double min_range, double max_use_range,
                          std::span<const Point2> directions) const {
  if (!directions.empty() && directions.size() != ranges.size())
    throw Error("LaserScan::endpoints: " + std::to_string(directions.size()) + " beam directions for " +
                std::to_string(ranges.size()) + " beams");
  out.clear();
  out.reserve(ranges.size());
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    if (status(i) != BeamStatus::kValid) continue;
    const double r = ranges[i];
    if (r < min_range || r >= max_use_range) continue;
    out.push_back(directions.empty() ? endpoint(i) : endpoint(i, directions[i]));
  }
}

std::span<const Point2> BeamDirections::of(const LaserScan& scan) {
  const auto min_bits = std::bit_cast<std::uint64_t>(scan.angle_min);
  const auto increment_bits = std::bit_cast<std::uint64_t>(scan.angle_increment);
  if (directions_.size() != scan.size() || min_bits != angle_min_bits_ || increment_bits != angle_increment_bits_) {
    directions_.resize(scan.size());
    for (std::size_t i = 0; i < scan.size(); ++i) {
      const double a = scan.bearing(i);
      directions_[i] = {std::cos(a), std::sin(a)};
    }
    angle_min_bits_ = min_bits, angle_increment_bits_ = increment_bits;
  }
  return directions_;
}

void set_flaser_geometry(LaserScan& scan) {
  const double n = static_cast<double>(scan.ranges.size());
  constexpr double kPi = std::numbers::pi;
  if (scan.ranges.size() < 2) {
    scan.angle_min = 0.0;
    scan.angle_increment = 0.0;
  } else if (scan.ranges.size() % 2 == 1) {
    scan.angle_increment = kPi / (n - 1.0);
    scan.angle_min = -kPi / 2.0;
  } else {
    scan.angle_increment = kPi / n;
    scan.angle_min = -kPi / 2.0 + scan.angle_increment / 2.0;
  }
}

std::uint64_t scan_fingerprint(const LaserScan& scan) {
  // splitmix64's finalizer over each reading in turn: every bit of a reading moves the whole hash.
  const auto mix = [](std::uint64_t h, std::uint64_t v) {
    h ^= v + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    h ^= h >> 30, h *= 0xbf58476d1ce4e5b9ULL;
    h ^= h >> 27, h *= 0x94d049bb133111ebULL;
    return h ^ (h >> 31);
  };
  std::uint64_t h = mix(0x6c73686c6f63ULL, scan.ranges.size());
  for (const float r : scan.ranges) {
    // NaN, inf and out-of-range readings all read as "none": one code.
    const bool finite = std::isfinite(r) && std::abs(r) < 1e6f;
    h = mix(h, finite ? static_cast<std::uint64_t>(std::llround(static_cast<double>(r) * 100.0)) : ~0ULL);
  }
  return h;
}

}  // namespace lshloc
