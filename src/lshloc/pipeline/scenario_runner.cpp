#include "lshloc/pipeline/scenario_runner.hpp"

#include <chrono>
#include <ctime>

namespace lshloc {

namespace {
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
}  // namespace

double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::vector<ScanEstimate> ScenarioRun::scan_estimates() const {
  std::vector<ScanEstimate> out;
  out.reserve(estimates.size());
  for (const auto& e : estimates) out.push_back({e.has_estimate, e.submap, e.pose, e.localized, e.mean_score});
  return out;
}

ScenarioRun run_scenario(const Scenario& scenario, ScenarioRunConfig config, const Progress& progress,
                         const LocalizerObserver& observer) {
  ScenarioRun run;
  GlobalMap map(config.map);
  for (const Submap& s : scenario.submaps) map.add_submap(s.name);

  // Mapper robots in parallel: one scan of each submap per round.
  std::vector<std::size_t> fed(scenario.submaps.size(), 0);
  const auto feed_until = [&](double share) {
    bool any = true;
    while (any) {
      any = false;
      for (std::size_t r = 0; r < scenario.submaps.size(); ++r) {
        const auto& scans = scenario.submaps[r].scans;
        const auto limit = static_cast<std::size_t>(share * static_cast<double>(scans.size()) + 0.5);
        if (fed[r] < std::min(limit, scans.size())) {
          map.add_scan(static_cast<std::uint32_t>(r), scans[fed[r]], scans[fed[r]].pose);
          ++fed[r];
          any = true;
        }
      }
    }
  };
  auto t0 = Clock::now();
  feed_until(config.map_share_before_target);
  run.map_build_s = seconds_since(t0);

  config.localizer.scan_matcher.laser_offset = scenario.target.laser_offset;
  Localizer localizer(map, config.localizer);
  const auto& scans = scenario.target.scans;
  run.estimates.reserve(scans.size());
  run.cpu_s.reserve(scans.size());
  const double cpu0 = process_cpu_seconds();
  double mapping_cpu = 0.0;
  t0 = Clock::now();
  for (std::size_t i = 0; i < scans.size(); ++i) {
    if (config.map_share_before_target < 1.0) {
      // The rest of the map arrives while the target moves.
      const double share = config.map_share_before_target +
                           (1.0 - config.map_share_before_target) * static_cast<double>(i + 1) /
                               static_cast<double>(scans.size());
      const double c0 = process_cpu_seconds();
      feed_until(share);
      mapping_cpu += process_cpu_seconds() - c0;
    }
    run.estimates.push_back(localizer.add_scan(scans[i]));
    run.cpu_s.push_back(process_cpu_seconds() - cpu0 - mapping_cpu);
    if (observer) observer(i, localizer);
    if (progress) progress(i + 1, scans.size());
  }
  run.localize_s = seconds_since(t0);
  run.localize_cpu_s = run.cpu_s.empty() ? 0.0 : run.cpu_s.back();
  if (scans.size() > 1) run.log_duration_s = scans.back().timestamp - scans.front().timestamp;
  if (!run.estimates.empty() && run.estimates.back().has_estimate) {
    const LocalizationEstimate& last = run.estimates.back();
    for (const LocalPoint& x : localizer.ransac().features()) {
      const Point2 g = last.T_submap_local.transform(Point2(x.x, x.y));
      const double th = last.T_submap_local.transform_angle(x.theta);
      (map.occupancy().probe(last.submap, g.x(), g.y(), th) & cell_flags::kOccupied ? run.final_inliers
                                                                                     : run.final_outliers)
          .push_back(g);
    }
  }
  run.map = map.stats();
  run.localizer = localizer.stats();
  return run;
}

}  // namespace lshloc
