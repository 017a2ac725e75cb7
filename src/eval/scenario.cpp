#include "lshloc/eval/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "lshloc/common/error.hpp"

namespace lshloc {

const std::vector<std::string>& canonical_building_order() {
  static const std::vector<std::string> order = {
      "fr079",      "intel",     "aces",       "fr101",           "mit-csail",         "acapulco",
      "belgioioso", "edmonton",  "fhw",        "freiburg-campus", "infinite-corridor", "orebro",
      "seattle",    "fr-clinic", "mit-killian"};
  return order;
}

std::size_t default_window_start(const std::string& building) {
  if (building == "fr079" || building == "fr101") return 2000;
  if (building == "intel") return 5000;
  if (building == "aces") return 3000;
  return 0;
}

std::vector<std::string> other_buildings(const ScenarioConfig& config) {
  const auto& all = canonical_building_order();
  if (std::find(all.begin(), all.end(), config.building) == all.end()) {
    throw Error("unknown building '" + config.building + "'");
  }
  std::vector<std::string> others;
  for (const auto& b : all) {
    if (b != config.building) others.push_back(b);
  }
  if (config.submaps == 0 || config.submaps > all.size()) {
    throw Error("--submaps " + std::to_string(config.submaps) + " is out of range: there are " +
                std::to_string(all.size()) + " real buildings (1.." + std::to_string(all.size()) + ")");
  }
  if (config.seed != 0) {
    std::mt19937_64 rng(config.seed);
    std::shuffle(others.begin(), others.end(), rng);
  }
  others.resize(config.submaps - 1);
  return others;
}

void split_target_building(const BuildingRecording& rec, const ScenarioConfig& config, Submap& map_side,
                           TargetRun& target) {
  const auto& raw = rec.raw_scans;
  if (config.length == 0) throw Error("the target window is empty: give a length of at least 1 scan");
  if (config.start >= raw.size() || config.length > raw.size() - config.start) {
    throw Error(rec.name + ": the window of " + std::to_string(config.length) + " scans from scan " +
                std::to_string(config.start) + " does not fit its raw log of " + std::to_string(raw.size()) + " scans");
  }
  const double t_begin = raw[config.start].timestamp - config.guard_s;
  const double t_end = raw[config.start + config.length - 1].timestamp + config.guard_s;
  const auto outside = [&](double t) { return t < t_begin || t > t_end; };

  map_side = {};
  map_side.name = rec.name;
  if (!rec.corrected_scans.empty()) {
    if (rec.truth.size() != rec.corrected_scans.size()) {
      throw Error(rec.name + ": the poses file has " + std::to_string(rec.truth.size()) +
                  " lines but the corrected log has " + std::to_string(rec.corrected_scans.size()) +
                  " scans; they must correspond line by line");
    }
    for (std::size_t k = 0; k < rec.corrected_scans.size(); ++k) {
      if (outside(rec.truth[k].timestamp)) map_side.scans.push_back(rec.corrected_scans[k]);
    }
  } else {
    // No corrected log: the mapper robot's own SLAM gives the map poses,
    // from the raw scans outside the window only.
    map_side.poses_from_slam = true;
    std::vector<LaserScan> kept;
    for (const auto& s : raw) {
      if (outside(s.timestamp)) kept.push_back(s);
    }
    map_side.scans = slam_mapped_scans(kept, rec.laser_offset);
  }

  target = {};
  target.building = rec.name;
  target.start = config.start;
  target.laser_offset = rec.laser_offset;
  target.scans.assign(raw.begin() + static_cast<std::ptrdiff_t>(config.start),
                      raw.begin() + static_cast<std::ptrdiff_t>(config.start + config.length));
  target.truth.assign(target.scans.size(), std::nullopt);
  const auto truth_scan = join_truth_to_scans(target.scans, rec.truth, rec.corrected_scans, config.truth_tolerance_s);
  for (std::size_t k = 0; k < truth_scan.size(); ++k) {
    if (truth_scan[k]) target.truth[*truth_scan[k]] = rec.truth[k].pose;
  }
}

bool same_ranges(const LaserScan& a, const LaserScan& b) {
  if (a.ranges.size() != b.ranges.size()) return false;
  for (std::size_t i = 0; i < a.ranges.size(); ++i) {
    const float x = a.ranges[i], y = b.ranges[i];
    if (std::isnan(x) != std::isnan(y) || (!std::isnan(x) && std::abs(x - y) > 0.006f)) return false;
  }
  return true;
}

std::vector<std::optional<std::size_t>> join_truth_to_scans(std::span<const LaserScan> scans,
                                                            std::span<const StampedPose> truth,
                                                            std::span<const LaserScan> truth_scans,
                                                            double tolerance_s) {
  std::vector<std::size_t> order(scans.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return scans[a].timestamp < scans[b].timestamp; });
  const bool have_ranges = truth_scans.size() == truth.size();
  std::vector<std::optional<std::size_t>> out(truth.size());
  std::vector<bool> taken(scans.size(), false);
  for (std::size_t k = 0; k < truth.size(); ++k) {
    const double t = truth[k].timestamp;
    auto it = std::lower_bound(order.begin(), order.end(), t - tolerance_s,
                               [&](std::size_t i, double v) { return scans[i].timestamp < v; });
    std::optional<std::size_t> nearest, identical;
    for (; it != order.end() && scans[*it].timestamp <= t + tolerance_s; ++it) {
      if (taken[*it]) continue;
      const auto closer = [&](const std::optional<std::size_t>& best) {
        return !best || std::abs(scans[*it].timestamp - t) < std::abs(scans[*best].timestamp - t);
      };
      if (closer(nearest)) nearest = *it;
      if (have_ranges && same_ranges(scans[*it], truth_scans[k]) && closer(identical)) identical = *it;
    }
    out[k] = identical ? identical : nearest;
    if (out[k]) taken[*out[k]] = true;
  }
  return out;
}

}  // namespace lshloc
