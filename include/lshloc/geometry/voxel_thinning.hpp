#pragma once
// Thinning of 2-D points: one point per square cell (the scan matcher's local
// map, the SLAM nodes, the map figures), or points a spacing apart along a
// scan (scan points, map endpoints, data-points).
// Lengths [m] (inv_voxel in 1/m).
// Stateless; safe from any thread while no other thread uses the vector being
// thinned.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "lshloc/common/saturated_cell.hpp"
#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

/// The key of the square cell holding p, for cells of side 1 / inv_voxel.
inline std::uint64_t voxel_key(const Point2& p, double inv_voxel) {
  const std::int32_t ix = saturated_cell(p.x() * inv_voxel), iy = saturated_cell(p.y() * inv_voxel);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(ix)) << 32) | static_cast<std::uint32_t>(iy);
}

/// Keeps, in each cell of side `voxel` [m], the first of `points` in their
/// order, and keeps the survivors in that order (so callers choose which
/// point a cell keeps by ordering the input). `position_of(point)` gives a
/// point's Point2. Deterministic; O(n): the cells seen so far live in an
/// open-addressing set (the scan matcher rebuilds its local map of ~20,000
/// points this way at every keyframe). voxel <= 0 keeps everything.
template <typename T, typename PositionOf>
void thin_to_voxels(std::vector<T>& points, double voxel, PositionOf position_of) {
  if (points.size() < 2 || !(voxel > 0.0)) return;
  const double inv = 1.0 / voxel;
  // A power of two at least twice the points: probes stay short. ~0 marks
  // an empty slot, so cell (-1, -1), whose key it is, is tracked apart.
  std::size_t capacity = 16;
  while (capacity < 2 * points.size()) capacity *= 2;
  const std::size_t mask = capacity - 1;
  constexpr std::uint64_t kEmpty = ~std::uint64_t{0};
  std::vector<std::uint64_t> seen(capacity, kEmpty);
  bool seen_minus_one = false;
  std::size_t kept = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::uint64_t key = voxel_key(position_of(points[i]), inv);
    if (key == kEmpty) {
      if (seen_minus_one) continue;
      seen_minus_one = true;
    } else {
      std::size_t slot = static_cast<std::size_t>((key * 0x9e3779b97f4a7c15ull) >> 32) & mask;
      while (seen[slot] != kEmpty && seen[slot] != key) slot = (slot + 1) & mask;
      if (seen[slot] == key) continue;
      seen[slot] = key;
    }
    if (kept != i) points[kept] = std::move(points[i]);
    ++kept;
  }
  points.resize(kept);
}

/// Thinning along a scan: calls visit(point) for each of `points`, in order,
/// that lies at least `spacing` [m] from the last one visited (the first
/// always): cheaper than voxels and it keeps the beam order.
/// `position_of(point)` gives a point's Point2.
template <typename Points, typename PositionOf, typename Visit>
void for_each_spaced(const Points& points, double spacing, PositionOf position_of, Visit visit) {
  bool any = false;
  Point2 last;
  for (const auto& p : points) {
    const Point2 position = position_of(p);
    if (any && (position - last).norm() < spacing) continue;
    any = true;
    last = position;
    visit(p);
  }
}

/// for_each_spaced() in place: keeps only the points it visits.
template <typename T, typename PositionOf>
void thin_spaced(std::vector<T>& points, double spacing, PositionOf position_of) {
  std::size_t kept = 0;
  // A kept point moves to an index at most its own, after it was read.
  for_each_spaced(points, spacing, position_of, [&](const T& p) { points[kept++] = p; });
  points.resize(kept);
}

/// thin_to_voxels() of plain points.
inline void thin_to_voxels(std::vector<Point2>& points, double voxel) {
  thin_to_voxels(points, voxel, [](const Point2& p) -> const Point2& { return p; });
}

}  // namespace lshloc
