#include "lshloc/runtime/localize_run.hpp"

#include <algorithm>
#include <chrono>
#include <mutex>
#include <string>

#include "lshloc/common/cpu_time.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"

namespace lshloc {

namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

void RunConfig::validate() const {
  map.validate();
  localizer.validate();
  require(map_share_before_target > 0.0 && map_share_before_target <= 1.0, "RunConfig.map_share_before_target",
          "in (0, 1]", map_share_before_target);
}

MapFeeder::MapFeeder(GlobalMap& map, const std::vector<Submap>& submaps)
    : map_(map), submaps_(submaps), fed_(submaps.size(), 0) {
  for (const Submap& s : submaps) ids_.push_back(map.add_submap(s.name));
}

MapFeeder::MapFeeder(GlobalMap& map, const std::vector<Submap>& submaps, std::vector<std::uint32_t> ids)
    : map_(map), submaps_(submaps), ids_(std::move(ids)), fed_(submaps.size(), 0) {
  if (ids_.size() != submaps_.size())
    throw Error("MapFeeder: expected one submap id per submap (" + std::to_string(submaps_.size()) + "), got " +
                std::to_string(ids_.size()));
}

void MapFeeder::feed_until(double share) {
  bool any = true;
  while (any) {
    any = false;
    for (std::size_t r = 0; r < submaps_.size(); ++r) {
      const auto& scans = submaps_[r].scans;
      const auto limit =
          std::min(scans.size(), static_cast<std::size_t>(share * static_cast<double>(scans.size()) + 0.5));
      if (fed_[r] < limit) {
        const LaserScan& scan = scans[fed_[r]];
        try {
          map_.add_scan(ids_[r], scan, scan.pose);
        } catch (const Error& e) {
          throw Error(submaps_[r].name + (scan.source_line ? ":" + std::to_string(scan.source_line) : "") + ": scan " +
                      std::to_string(fed_[r]) + " cannot enter the map: " + e.what());
        }
        ++fed_[r];
        any = true;
      }
    }
  }
}

LocalizationRun localize_target(const GlobalMap& map, const TargetRun& target, LocalizerConfig config,
                                const Progress& progress, const LocalizerObserver& observer,
                                const BeforeScan& before_scan, std::shared_mutex* map_mutex) {
  LocalizationRun run;
  LocalizationSession session(map, {.localizer = std::move(config)}, target.laser_offset, target.odometry, map_mutex);
  const LocalizerConfig& applied = session.localizer_config();
  const auto& scans = target.scans;
  run.estimates.reserve(scans.size());
  run.cpu_s.reserve(scans.size());
  const double cpu0 = thread_cpu_seconds();
  double excluded_cpu = 0.0;
  // Mapper scans and diagnostics run between target scans: not the localizer's cost.
  const auto excluded = [&](const auto& work) {
    const double c0 = thread_cpu_seconds();
    work();
    excluded_cpu += thread_cpu_seconds() - c0;
  };
  const auto t0 = Clock::now();
  for (std::size_t i = 0; i < scans.size(); ++i) {
    if (before_scan) excluded([&] { before_scan(i); });
    session.add_scan(scans[i], [&](const Localizer& localizer, const LocalizationEstimate& estimate) {
      run.cpu_s.push_back(thread_cpu_seconds() - cpu0 - excluded_cpu);
      run.estimates.push_back(estimate);
      if (observer) excluded([&] { observer(i, localizer, estimate); });
    });
    if (progress) progress(i + 1, scans.size());
  }
  std::shared_lock<std::shared_mutex> reading;  // the final look at the map below
  if (map_mutex) reading = std::shared_lock<std::shared_mutex>(*map_mutex);
  const Localizer& localizer = session.localizer();
  run.localize_s = seconds_since(t0);
  run.localize_cpu_s = run.cpu_s.empty() ? 0.0 : run.cpu_s.back();
  if (scans.size() > 1) run.log_duration_s = scans.back().timestamp - scans.front().timestamp;
  if (!run.estimates.empty() && run.estimates.back().has_estimate) {
    // The newest surface data-points placed by the final estimate.
    const LocalizationEstimate& last = run.estimates.back();
    const auto points = localizer.ransac().data_points();
    const std::size_t window = std::min(points.size(), applied.ransac.recent_window);
    for (const LocalPoint& x : points.last(window)) {
      if (x.kind != LocalPoint::Kind::kSurface) continue;
      const Point2 g = last.T_submap_local.transform(Point2(x.x, x.y));
      const double th = last.T_submap_local.transform_angle(x.theta);
      (map.occupancy().probe(last.submap, g.x(), g.y(), th) & cell_flags::kOccupied ? run.final_inliers
                                                                                    : run.final_outliers)
          .push_back(g);
    }
  }
  run.map = map.stats();
  for (std::uint32_t id = 0; id < map.submap_count(); ++id) run.submap_names.push_back(map.submap_name(id));
  run.localizer = localizer.stats();
  // The localizer compared each scan with those before it; a whole run can
  // also compare it with those after.
  std::vector<double> stamps(scans.size());
  for (std::size_t i = 0; i < scans.size(); ++i) stamps[i] = scans[i].timestamp;
  const StampClashStats later = mark_stamp_clashes(stamps, run.estimates, applied.stamp_clash);
  run.stamp_clash = run.localizer.stamp_clash;
  run.stamp_clash.clashing_scans += later.clashing_scans;
  run.stamp_clash.flags_withheld += later.flags_withheld;
  return run;
}

}  // namespace lshloc
