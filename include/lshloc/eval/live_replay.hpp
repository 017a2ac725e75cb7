#pragma once
// The live scenario (docs/design.md section 6): every submap starts empty at
// the target's first scan, and each building's mapper robot replays its map
// scans in log order, faster than the target by mapper_speed, while the
// target localizes at log speed; mapper and target events interleave by
// their replay time. Records, per target scan, whether its true place was
// already mapped, and what the localizer and the mappers cost.
// Times [s] (replay time: 0 at the target's first scan), lengths [m].
// Thread safety: plain values and functions with no shared state. A run owns
// its map: run_live_scenario on one thread (the deterministic replay),
// run_live_threaded with its own mapper threads and a shared_mutex.
#include <cstdint>
#include <optional>
#include <vector>

#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/eval/scenario.hpp"
#include "lshloc/eval/scenario_runner.hpp"

namespace lshloc {

struct LiveReplayConfig {
  double mapper_speed = 4.0;  ///< a mapper replays this many seconds of its log per second of the target's
  /// [s] a longer pause between two consecutive scans of one mapper (the
  /// target's window and guard cut out of its own building, a robot
  /// standing still) replays as this long
  double max_gap_s = 5.0;
  /// [m] a target scan's place is mapped once a scan of the target's
  /// building this close to its true pose is in the map
  double mapped_radius_m = 2.0;

  /// Throws lshloc::Error naming the field when a value is out of range.
  void validate() const;
};

/// One mapper scan of the replay: submaps[submap].scans[scan] enters the map
/// at replay time time_s.
struct MapperEvent {
  double time_s = 0.0;
  std::uint32_t submap = 0;
  std::uint32_t scan = 0;
};

/// Every submap's scans with their replay times, merged by time (ties in
/// submap order). A mapper's first scan enters at time 0; each next one
/// after the log time since its previous one (at most max_gap_s, never
/// negative) divided by mapper_speed.
std::vector<MapperEvent> mapper_schedule(const std::vector<Submap>& submaps, const LiveReplayConfig& config);

/// What a live run adds to a scenario run.
struct LiveRun {
  LocalizationRun run;
  /// Per target scan: 1 when it has ground truth (measured or interpolated,
  /// interpolate_truth) and a scan of the target's building within
  /// mapped_radius_m of that truth was in the map when it was localized, else 0.
  std::vector<std::uint8_t> place_mapped;
  std::vector<std::size_t> map_scans_in;  ///< per target scan: mapper scans in the map when it was localized
  std::size_t mapper_scans = 0;           ///< mapper scans fed over the whole run
  std::size_t mapper_scans_total = 0;     ///< scans the mappers had (the rest came after the target's last scan)
  double mapper_cpu_s = 0.0;              ///< [s] CPU time of the threads feeding them, while they fed
};

/// Runs `scenario` live: the target's scans at log speed, each submap's
/// scans as mapper_schedule() orders them, fed before the first target scan
/// at or after their time. Single-threaded and deterministic.
LiveRun run_live_scenario(const Scenario& scenario, const RunConfig& config, const LiveReplayConfig& live,
                          const Progress& progress = {}, const LocalizerObserver& observer = {});

/// The real-time mode (`eval --threads`). With `live`, mapper threads feed
/// the map while the target localizes on the calling thread: each mapper
/// scan enters once the target has reached its replay time (so never ahead
/// of run_live_scenario's order, possibly behind it); submaps are spread
/// over at most max_mapper_threads threads. Without `live`, the map is built
/// first and the writers stay idle: the frozen-map reference. A mapper
/// holds a shared_mutex exclusively while it writes every scan that is due
/// (one per scan let the target's back-to-back reads starve the writers);
/// the target holds it shared for each of its scans, so it waits at most
/// one mapper's due scans. Not deterministic: the interleaving is the threads'.
LiveRun run_live_threaded(const Scenario& scenario, const RunConfig& config, const LiveReplayConfig& live_config,
                          bool live, const Progress& progress = {}, std::size_t max_mapper_threads = 16);

/// The live metrics (docs/design.md section 6) beside the batch ones.
struct LiveMetrics {
  std::optional<std::size_t> first_mapped_at;  ///< first target scan whose place was mapped
  bool final_place_mapped = false;             ///< the last judged scan's place was mapped
  /// Scans from first_mapped_at to localized_at (0 when it localized
  /// earlier); nullopt when either is missing.
  std::optional<std::size_t> mapped_to_localized;
  std::size_t confident_wrong_before_mapped = 0;  ///< confident-but-wrong scans whose place was not mapped yet
  std::size_t confident_wrong_after_mapped = 0;   ///< ... and those whose place was
  double ms_per_scan_p99 = 0.0;                   ///< [ms] 99th percentile of the localizer's CPU per target scan
  double map_scans_per_s = 0.0;                   ///< mapper scans fed per CPU second of feeding
};

LiveMetrics evaluate_live(const LiveRun& live, const LocalizationMetrics& metrics);

/// [ms] the 99th percentile (nearest rank) of the CPU time per scan, from
/// cumulative CPU seconds per scan (LocalizationRun::cpu_s); 0 for no scans.
double ms_per_scan_p99(const std::vector<double>& cumulative_cpu_s);

}  // namespace lshloc
