#pragma once
// A localization run: feeds mapper robots' submaps to a GlobalMap as robots
// working in parallel would, runs a target's scans through a
// LocalizationSession, and records the estimates with their costs.
// Poses [m, rad]; times [s], CPU (the calling thread's) or wall clock as each
// field says.
// Thread safety: localize_target only reads `map` and MapFeeder writes it,
// but a GlobalMap is not thread-safe (docs/design.md section 5): keep each
// map on one thread, or give localize_target the shared_mutex its writers
// lock exclusively (the live threaded mode).
#include <functional>
#include <shared_mutex>
#include <vector>

#include "lshloc/localization/global_map.hpp"
#include "lshloc/localization/localizer.hpp"
#include "lshloc/runtime/inputs.hpp"
#include "lshloc/runtime/session.hpp"

namespace lshloc {

/// The settings of a run: the map's, the localizer's, and how much of the
/// map is there before the target starts.
struct RunConfig {
  GlobalMapConfig map;
  LocalizerConfig localizer;
  /// Share (0..1] of each submap's scans fed before the target starts (one
  /// scan of each submap in turn, as robots mapping in parallel would); the
  /// rest arrives between target scans.
  double map_share_before_target = 1.0;

  /// The map's and the localizer's validate(), and the share in (0, 1].
  void validate() const;
};

/// What one localization run produced, scan by scan, with its costs.
struct LocalizationRun {
  std::vector<LocalizationEstimate> estimates;  ///< per target scan
  std::vector<double> cpu_s;                    ///< [s] CPU time spent on the target up to and including each scan
  double map_build_s = 0.0;                     ///< [s] wall time to feed every mapper scan
  double localize_s = 0.0;                      ///< [s] wall time of all target scans
  double localize_cpu_s = 0.0;                  ///< [s] CPU time of all target scans
  double log_duration_s = 0.0;                  ///< [s] time the target's scans span in the log
  GlobalMapStats map;
  LocalizerStats localizer;
  /// Scans stamped together with another at a different pose, over the
  /// whole run (those after each scan too), and how many of them were flagged.
  StampClashStats stamp_clash;
  /// The newest surface data-points of iRANSAC placed by the final estimate,
  /// split by whether they hit the map (for the paper's Fig. 6 style figure).
  std::vector<Point2> final_inliers, final_outliers;
  /// The map's submap names by id at the end of the run (what estimates' submap ids name).
  std::vector<std::string> submap_names;
};

/// Progress callback: (target scans done, total); may be empty.
using Progress = std::function<void(std::size_t, std::size_t)>;
/// Called after each target scan with its index, the localizer and its
/// estimate (for diagnostics that look inside it; its CPU time is not
/// counted as the localizer's); may be empty.
using LocalizerObserver = std::function<void(std::size_t, const Localizer&, const LocalizationEstimate&)>;

/// Feeds submaps' scans (with their map poses) to a global map as mapper
/// robots working in parallel would: one scan of each submap in turn.
class MapFeeder {
 public:
  /// Opens one submap of `map` per entry of `submaps` (which must outlive it).
  MapFeeder(GlobalMap& map, const std::vector<Submap>& submaps);
  /// Feeds submaps[i] into the map's existing submap ids[i] instead.
  MapFeeder(GlobalMap& map, const std::vector<Submap>& submaps, std::vector<std::uint32_t> ids);
  /// Feeds scans until this share (0..1) of every submap is in the map.
  void feed_until(double share);
  /// The map's id of submaps[i].
  std::uint32_t submap_id(std::size_t i) const { return ids_.at(i); }

 private:
  GlobalMap& map_;
  const std::vector<Submap>& submaps_;
  std::vector<std::uint32_t> ids_;
  std::vector<std::size_t> fed_;
};

/// Called before target scan i; its CPU time is not counted as the target's.
using BeforeScan = std::function<void(std::size_t)>;

/// Replays a target's scans through a new LocalizationSession over `map` (its
/// scan matcher takes the target's laser offset, unless the config gives one
/// for a target without; a config offset other than the target's is an error).
/// The localizer's cost is the calling thread's CPU time. With `map_mutex`,
/// other threads may write the map meanwhile: each target scan (and the
/// observer's look) holds it shared, so writers must hold it exclusively.
/// At the end each estimate stamped together with a later scan elsewhere is
/// marked `stamp_clash` (the observer saw it unmarked). map_build_s stays 0.
LocalizationRun localize_target(const GlobalMap& map, const TargetRun& target, LocalizerConfig config,
                                const Progress& progress = {}, const LocalizerObserver& observer = {},
                                const BeforeScan& before_scan = {}, std::shared_mutex* map_mutex = nullptr);

}  // namespace lshloc
