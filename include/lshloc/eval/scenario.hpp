#pragma once
// Evaluation scenarios from the dataset (docs/design.md section 6): building
// recordings, the canonical order of buildings, and how the target's building
// is split into its submap and the run (the run's inputs: runtime/inputs.hpp).
// Lengths [m], angles [rad], times [s].
// Thread safety: plain values; the functions share no state (the canonical
// order is a constant built once) and are safe from any thread.
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "lshloc/runtime/inputs.hpp"

namespace lshloc {

/// The canonical order in which other buildings join a global map (the order
/// the MRPT peer uses: intel, aces, fr101, mit-csail, then the Radish logs
/// alphabetically, then the logs with no corrected poses).
const std::vector<std::string>& canonical_building_order();

/// The first raw scan of a building's default window (RESULTS.md): fr079
/// and fr101 2000, intel 5000, aces 3000, any other building 0.
std::size_t default_window_start(const std::string& building);

/// Names of the R-1 other buildings for a target, in the order config.seed gives.
std::vector<std::string> other_buildings(const ScenarioConfig& config);

/// Whether two scans hold the same ranges (to the 2 decimals logs print;
/// invalid readings alike).
bool same_ranges(const LaserScan& a, const LaserScan& b);

/// For each ground-truth pose, the one scan it belongs to: among `scans`
/// within tolerance_s of its stamp and not yet taken, the nearest whose ranges
/// are truth_scans[k]'s (when truth_scans holds one scan per pose), else the
/// nearest. Where a raw log bunches stamps 1 ms apart, a join of each scan to
/// the nearest pose gives scans a neighbour's pose (docs/results/live-map.md).
std::vector<std::optional<std::size_t>> join_truth_to_scans(std::span<const LaserScan> scans,
                                                            std::span<const StampedPose> truth,
                                                            std::span<const LaserScan> truth_scans, double tolerance_s);

/// The target's window and its own submap, built from its recording: map scans
/// are corrected scans whose raw time stamp lies more than guard_s outside the
/// window (or, with no corrected log, raw scans outside it with poses from
/// slam_mapped_scans()).
/// Throws lshloc::Error when the window does not fit the log.
void split_target_building(const BuildingRecording& rec, const ScenarioConfig& config, Submap& map_side,
                           TargetRun& target);

}  // namespace lshloc
