#pragma once
// Correlative scan matching (Olson 2009, "Real-time correlative scan
// matching"): an exhaustive search over a window of poses for the one that
// puts a query scan's points on a blurred likelihood grid of reference
// points, exact by branch and bound over a max-filtered grid. Unlike ICP it
// needs no close initial guess, which is what closing a loop after a long
// drift takes; the runner-up away from the best pose tells whether the match
// is unique (a corridor is not).
// Lengths [m], angles [rad] except angle_step_deg [deg]; scores unitless in
// [0, 1].
// Thread safety: one CorrelativeMatcher per thread (see the class).
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "lshloc/geometry/pose2.hpp"

namespace lshloc {

struct CorrelativeMatcherConfig {
  double cell = 0.05;                  ///< [m] likelihood grid cell = finest translation step
  double sigma = 0.08;                 ///< [m] blur of the likelihood around each reference point
  int block = 6;                       ///< [cells] coarse translation step of the branch and bound
  double angle_step_deg = 0.5;         ///< [deg] heading step
  std::size_t max_query_points = 150;  ///< query points used (evenly subsampled)
  double runner_up_distance = 1.0;     ///< [m] the runner-up is the best pose at least this far from the best
  void validate() const;
};

struct CorrelativeMatch {
  bool found = false;         ///< false with no reference or query points
  Pose2 pose;                 ///< the query frame's pose in the reference frame
  double score = 0.0;         ///< mean likelihood of the query points at `pose`, in [0, 1]
  double runner_up = 0.0;     ///< the best score of a pose runner_up_distance or more away
  std::size_t evaluated = 0;  ///< poses scored at full resolution
};

/// Not thread-safe (scratch is reused); one instance per thread.
class CorrelativeMatcher {
 public:
  /// Cells of each lookup grid beyond which matching throws (3 float grids
  /// of 128 MiB): a reference that large comes from a broken input.
  static constexpr std::size_t kMaxGridCells = std::size_t{1} << 25;

  explicit CorrelativeMatcher(CorrelativeMatcherConfig config = {});

  /// Searches poses guess * (tx, ty, 0) with |tx|, |ty| <= window_m and
  /// headings within window_rad of guess for where `query` (points in the
  /// query's own frame) best fits `reference` (points in the reference frame).
  CorrelativeMatch match(std::span<const Point2> reference, std::span<const Point2> query, const Pose2& guess,
                         double window_m, double window_rad);

  const CorrelativeMatcherConfig& config() const { return config_; }

 private:
  void build_grids(std::span<const Point2> reference);
  float fine_at(std::int32_t ix, std::int32_t iy) const;
  float coarse_at(std::int32_t ix, std::int32_t iy) const;

  CorrelativeMatcherConfig config_;
  double x0_ = 0.0, y0_ = 0.0;  ///< [m] corner of cell (0, 0)
  std::int32_t w_ = 0, h_ = 0;
  std::vector<float> fine_;    ///< likelihood per cell
  std::vector<float> coarse_;  ///< max of fine over [ix, ix + block) x [iy, iy + block)
  std::vector<float> scratch_;
};

}  // namespace lshloc
