#include "lshloc/eval/live_replay.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <mutex>
#include <numeric>
#include <shared_mutex>
#include <span>
#include <string>
#include <thread>

#include "lshloc/common/cpu_time.hpp"
#include "lshloc/common/error.hpp"

namespace lshloc {

namespace {

/// Whether a scan of the target's building within `radius` of `truth` is among `poses`.
bool place_is_mapped(const std::vector<Pose2>& poses, const Pose2& truth, double radius) {
  return std::any_of(poses.begin(), poses.end(),
                     [&](const Pose2& p) { return translation_distance(p, truth) <= radius; });
}

/// The start of a replay: an empty submap in `map` per scenario submap (the
/// returned ids, in order) and `out` sized for the target's scans.
std::vector<std::uint32_t> open_replay(const Scenario& scenario, std::size_t mapper_scans, GlobalMap& map,
                                       LiveRun& out) {
  std::vector<std::uint32_t> ids;
  for (const Submap& s : scenario.submaps) ids.push_back(map.add_submap(s.name));
  out.mapper_scans_total = mapper_scans;
  out.place_mapped.assign(scenario.target.scans.size(), 0);
  out.map_scans_in.assign(scenario.target.scans.size(), 0);
  return ids;
}

}  // namespace

void LiveReplayConfig::validate() const {
  require(std::isfinite(mapper_speed) && mapper_speed > 0.0 && mapper_speed <= 1e6, "LiveReplayConfig.mapper_speed",
          "a number in (0, 1e6]", mapper_speed);
  require(std::isfinite(max_gap_s) && max_gap_s >= 0.0, "LiveReplayConfig.max_gap_s", "a finite number >= 0",
          max_gap_s);
  require(std::isfinite(mapped_radius_m) && mapped_radius_m > 0.0, "LiveReplayConfig.mapped_radius_m",
          "a finite number > 0", mapped_radius_m);
}

std::vector<MapperEvent> mapper_schedule(const std::vector<Submap>& submaps, const LiveReplayConfig& config) {
  config.validate();
  std::vector<MapperEvent> events;
  for (std::size_t r = 0; r < submaps.size(); ++r) {
    const auto& scans = submaps[r].scans;
    double t = 0.0;
    for (std::size_t j = 0; j < scans.size(); ++j) {
      if (j > 0) {
        const double dt = scans[j].timestamp - scans[j - 1].timestamp;
        // NaN-safe: a gap that is no number replays as none.
        t += (dt > 0.0 ? std::min(dt, config.max_gap_s) : 0.0) / config.mapper_speed;
      }
      events.push_back({t, static_cast<std::uint32_t>(r), static_cast<std::uint32_t>(j)});
    }
  }
  // Stable: at equal times, the submaps' order (as the batch feeder takes them).
  std::stable_sort(events.begin(), events.end(),
                   [](const MapperEvent& a, const MapperEvent& b) { return a.time_s < b.time_s; });
  return events;
}

LiveRun run_live_scenario(const Scenario& scenario, const RunConfig& config, const LiveReplayConfig& live,
                          const Progress& progress, const LocalizerObserver& observer) {
  const std::vector<MapperEvent> events = mapper_schedule(scenario.submaps, live);
  GlobalMap map(config.map);
  LiveRun out;
  const std::vector<std::uint32_t> ids = open_replay(scenario, events.size(), map, out);
  const TargetRun& target = scenario.target;
  const JudgedTruth judged = interpolate_truth(target);
  const double start = target.scans.empty() ? 0.0 : target.scans.front().timestamp;
  std::size_t next = 0;
  std::vector<Pose2> target_building_in_map;  // poses of the target building's scans fed so far
  const double radius = live.mapped_radius_m;
  const BeforeScan feed = [&](std::size_t i) {
    const double now = target.scans[i].timestamp - start;
    const double cpu0 = thread_cpu_seconds();
    while (next < events.size() && events[next].time_s <= now) {
      const MapperEvent& e = events[next++];
      const LaserScan& scan = scenario.submaps[e.submap].scans[e.scan];
      map.add_scan(ids[e.submap], scan, scan.pose);
      if (e.submap == scenario.target_submap) target_building_in_map.push_back(scan.pose);
    }
    out.mapper_cpu_s += thread_cpu_seconds() - cpu0;
    out.map_scans_in[i] = next;
    if (const auto& truth = judged.pose[i])
      out.place_mapped[i] = place_is_mapped(target_building_in_map, *truth, radius);
  };
  out.run = localize_target(map, target, config.localizer, progress, observer, feed);
  out.mapper_scans = next;
  return out;
}

LiveRun run_live_threaded(const Scenario& scenario, const RunConfig& config, const LiveReplayConfig& live_config,
                          bool live, const Progress& progress, std::size_t max_mapper_threads) {
  const std::vector<MapperEvent> events = mapper_schedule(scenario.submaps, live_config);
  GlobalMap map(config.map);
  LiveRun out;
  const std::vector<std::uint32_t> ids = open_replay(scenario, events.size(), map, out);
  const TargetRun& target = scenario.target;
  const JudgedTruth judged = interpolate_truth(target);

  std::shared_mutex map_mutex;
  std::vector<Pose2> target_building_in_map;  // guarded by map_mutex
  std::size_t inserted = 0;                   // guarded by map_mutex
  // A mapper writes every scan that is due under one hold of the lock: one
  // hand-over (and wake-up of the waiting localizer) per batch, not per scan.
  const auto insert = [&](std::span<const MapperEvent* const> due) {
    const std::unique_lock<std::shared_mutex> writing(map_mutex);
    for (const MapperEvent* e : due) {
      const LaserScan& scan = scenario.submaps[e->submap].scans[e->scan];
      map.add_scan(ids[e->submap], scan, scan.pose);
      if (e->submap == scenario.target_submap) target_building_in_map.push_back(scan.pose);
      ++inserted;
    }
  };

  // The target's replay clock: target scans begun (kDone once it has finished).
  constexpr std::size_t kDone = static_cast<std::size_t>(-1);
  std::atomic<std::size_t> reached{0};
  std::vector<double> target_time(target.scans.size());
  for (std::size_t i = 0; i < target.scans.size(); ++i) {
    target_time[i] = target.scans[i].timestamp - target.scans.front().timestamp;
  }
  std::atomic<double> mapper_cpu_s{0.0};
  // A mapper's error (a scan the map refuses) ends the run with it, as on
  // one thread, instead of escaping its thread (std::terminate).
  std::mutex failure_mutex;
  std::exception_ptr failure;  // the first; written under failure_mutex before `failed` is set
  std::atomic<bool> failed{false};
  std::vector<std::thread> mappers;
  if (!live) {  // the batch feeder's order: the same map as run_scenario's
    const double cpu0 = thread_cpu_seconds();
    MapFeeder(map, scenario.submaps, ids).feed_until(1.0);
    out.mapper_cpu_s = thread_cpu_seconds() - cpu0;
    for (const LaserScan& scan : scenario.submaps[scenario.target_submap].scans)
      target_building_in_map.push_back(scan.pose);
    inserted = events.size();
  } else {
    const std::size_t threads =
        std::max<std::size_t>(1, std::min(max_mapper_threads, std::max<std::size_t>(scenario.submaps.size(), 1)));
    for (std::size_t t = 0; t < threads; ++t) {
      mappers.emplace_back([&, t, threads] {  // threads by value: this block ends before they do
        std::vector<const MapperEvent*> mine, due;
        for (const MapperEvent& e : events)
          if (e.submap % threads == t) mine.push_back(&e);
        double cpu = 0.0;
        try {
          for (std::size_t next = 0; next < mine.size();) {
            std::size_t r = 0;
            for (;;) {  // until the target has reached the next scan's time
              r = reached.load(std::memory_order_acquire);
              if (r == kDone) {
                mapper_cpu_s.fetch_add(cpu);
                return;
              }
              if (r > 0 && target_time[r - 1] >= mine[next]->time_s) break;
              reached.wait(r, std::memory_order_acquire);
            }
            due.clear();
            while (next < mine.size() && target_time[r - 1] >= mine[next]->time_s) due.push_back(mine[next++]);
            const double c0 = thread_cpu_seconds();
            insert(due);
            cpu += thread_cpu_seconds() - c0;
          }
        } catch (...) {
          const std::lock_guard<std::mutex> lock(failure_mutex);
          if (!failure) failure = std::current_exception();
          failed.store(true, std::memory_order_release);
        }
        mapper_cpu_s.fetch_add(cpu);
      });
    }
  }
  const double radius = live_config.mapped_radius_m;
  const BeforeScan advance = [&](std::size_t i) {
    if (failed.load(std::memory_order_acquire)) std::rethrow_exception(failure);
    if (live) {
      reached.store(i + 1, std::memory_order_release);
      reached.notify_all();
    }
    const std::shared_lock<std::shared_mutex> reading(map_mutex);
    out.map_scans_in[i] = inserted;
    if (const auto& truth = judged.pose[i])
      out.place_mapped[i] = place_is_mapped(target_building_in_map, *truth, radius);
  };
  try {
    out.run = localize_target(map, target, config.localizer, progress, {}, advance, &map_mutex);
  } catch (...) {
    reached.store(kDone, std::memory_order_release);
    reached.notify_all();
    for (std::thread& m : mappers) m.join();
    throw;
  }
  reached.store(kDone, std::memory_order_release);
  reached.notify_all();
  for (std::thread& m : mappers) m.join();
  if (failed.load(std::memory_order_acquire)) std::rethrow_exception(failure);
  out.mapper_scans = inserted;
  if (live) out.mapper_cpu_s = mapper_cpu_s.load();
  return out;
}

double ms_per_scan_p99(const std::vector<double>& cumulative_cpu_s) {
  if (cumulative_cpu_s.empty()) return 0.0;
  std::vector<double> per_scan(cumulative_cpu_s.size());
  std::adjacent_difference(cumulative_cpu_s.begin(), cumulative_cpu_s.end(), per_scan.begin());
  // Nearest rank: the smallest value with at least 99% of the scans at or below it.
  const std::size_t rank = static_cast<std::size_t>(std::ceil(0.99 * static_cast<double>(per_scan.size())));
  std::nth_element(per_scan.begin(), per_scan.begin() + static_cast<std::ptrdiff_t>(rank - 1), per_scan.end());
  return 1e3 * per_scan[rank - 1];
}

LiveMetrics evaluate_live(const LiveRun& live, const LocalizationMetrics& metrics) {
  if (live.place_mapped.size() != metrics.error_per_scan_m.size()) {
    throw Error("evaluate_live: " + std::to_string(live.place_mapped.size()) + " target scans in the run, " +
                std::to_string(metrics.error_per_scan_m.size()) + " in the metrics");
  }
  LiveMetrics m;
  const auto& mapped = live.place_mapped;
  const auto first = std::find(mapped.begin(), mapped.end(), std::uint8_t{1});
  if (first != mapped.end()) m.first_mapped_at = static_cast<std::size_t>(first - mapped.begin());
  // The last judged scan: the metrics' error is NaN exactly where a scan is not judged.
  for (std::size_t i = mapped.size(); i-- > 0;) {
    if (!std::isnan(metrics.error_per_scan_m[i])) {
      m.final_place_mapped = mapped[i] != 0;
      break;
    }
  }
  if (m.first_mapped_at && metrics.localized_at) {
    m.mapped_to_localized = *metrics.localized_at > *m.first_mapped_at ? *metrics.localized_at - *m.first_mapped_at : 0;
  }
  for (const std::size_t i : metrics.confident_wrong_scans) {
    (mapped[i] ? m.confident_wrong_after_mapped : m.confident_wrong_before_mapped) += 1;
  }
  m.ms_per_scan_p99 = ms_per_scan_p99(live.run.cpu_s);
  m.map_scans_per_s = live.mapper_cpu_s > 0.0 ? static_cast<double>(live.mapper_scans) / live.mapper_cpu_s : 0.0;
  return m;
}

}  // namespace lshloc
