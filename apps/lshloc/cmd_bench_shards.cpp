// `lshloc bench shards`: the scale-out design measured on one machine
// (docs/scale-out.md). A global map of R synthetic buildings is split by
// submap over K workers (submap k to worker k mod K), each with its own
// GlobalMap and Localizer on its own thread, as K worker processes would
// run; every target scan goes to all K, and a router merges their reports:
// the best mean score wins, and its margin is re-judged against the best
// place of every other worker, which its own localizer never saw.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "localizer_options.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/eval/localization_metrics.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"
#include "option_checks.hpp"
#include "process_memory.hpp"
#include "scenario_report.hpp"

namespace lshloc::app {

namespace {

struct ShardsOptions {
  std::size_t submaps = 100;
  std::vector<std::size_t> shards{1, 2, 4};
  std::size_t targets = 4;
  sim::SyntheticScenarioConfig world{.seed = 7, .map_scans = 3300, .target_scans = 300};
  LocalizerOptions localizer;
};

/// The router: per scan, the report of the worker with the best mean score,
/// its submap made global, its margin the smaller of its own and its lead
/// over every other worker's best, and its flag kept only while that margin
/// still meets the policy's.
std::vector<ScanEstimate> merge_reports(const std::vector<LocalizationRun>& workers,
                                        const std::vector<std::vector<std::uint32_t>>& global_ids, double min_margin) {
  const std::size_t scans = workers.front().estimates.size();
  std::vector<ScanEstimate> out(scans);
  for (std::size_t i = 0; i < scans; ++i) {
    std::size_t best = workers.size();
    for (std::size_t w = 0; w < workers.size(); ++w) {
      const LocalizationEstimate& e = workers[w].estimates[i];
      if (e.has_estimate && (best == workers.size() || e.mean_score > workers[best].estimates[i].mean_score)) best = w;
    }
    if (best == workers.size()) continue;
    const LocalizationEstimate& e = workers[best].estimates[i];
    double rival = 0.0;
    for (std::size_t w = 0; w < workers.size(); ++w)
      if (w != best && workers[w].estimates[i].has_estimate)
        rival = std::max(rival, workers[w].estimates[i].mean_score);
    const double margin = std::min(e.margin, e.mean_score - rival);
    out[i] = {true, global_ids[best].at(e.submap), e.pose, e.localized && margin >= min_margin, e.mean_score};
  }
  return out;
}

nlohmann::json run_sharded(const ShardsOptions& opt, std::size_t k, bool tty) {
  const RunConfig config = make_run_config(opt.localizer);
  std::vector<std::unique_ptr<GlobalMap>> maps;
  std::vector<std::vector<std::uint32_t>> global_ids(k);  // per worker: local submap id -> global index
  for (std::size_t w = 0; w < k; ++w) maps.push_back(std::make_unique<GlobalMap>(config.map));
  std::vector<TargetRun> targets;
  const auto t0 = std::chrono::steady_clock::now();
  for (std::size_t g = 0; g < opt.submaps; ++g) {
    std::vector<Submap> one(1);
    if (g < opt.targets) {
      sim::SplitBuilding split = sim::synthetic_split_building(opt.world, g, 1);
      one[0] = std::move(split.submap);
      targets.push_back(std::move(split.targets.at(0)));
    } else {
      one[0] = sim::synthetic_submap(opt.world.seed, g, opt.world.map_scans);
    }
    MapFeeder(*maps[g % k], one).feed_until(1.0);
    global_ids[g % k].push_back(static_cast<std::uint32_t>(g));
    if (tty) std::fprintf(stderr, "\r  K = %zu: mapped %zu/%zu buildings", k, g + 1, opt.submaps);
  }
  if (tty) std::fprintf(stderr, "\n");
  const double build_s = seconds_since(t0);
  std::size_t localized = 0, wrong = 0;
  std::vector<double> localized_at;
  double wall_s = 0.0, cpu_s = 0.0, merge_s = 0.0, scans = 0.0;
  nlohmann::json per_target = nlohmann::json::array();
  for (const TargetRun& target : targets) {
    std::vector<LocalizationRun> runs(k);
    const auto t1 = std::chrono::steady_clock::now();
    {
      std::vector<std::jthread> workers;
      for (std::size_t w = 0; w < k; ++w)
        workers.emplace_back([&, w] { runs[w] = localize_target(*maps[w], target, config.localizer); });
    }
    wall_s += seconds_since(t1);
    for (const auto& r : runs) cpu_s += r.localize_cpu_s;
    const auto t2 = std::chrono::steady_clock::now();
    const std::vector<ScanEstimate> merged = merge_reports(runs, global_ids, config.localizer.report.min_margin);
    merge_s += seconds_since(t2);
    scans += static_cast<double>(target.scans.size());
    const std::size_t target_global = static_cast<std::size_t>(&target - targets.data());
    const auto m = evaluate_localization(merged, interpolate_truth(target), static_cast<std::uint32_t>(target_global));
    localized += m.success, wrong += m.confident_wrong;
    if (m.success && m.localized_at) localized_at.push_back(static_cast<double>(*m.localized_at));
    per_target.push_back(target_outcome_json(target.building, m));
  }
  std::size_t features = 0;
  for (const auto& m : maps) features += m->stats().features;
  return {{"submaps", opt.submaps},
          {"shards", k},
          {"map_features", features},
          {"build_s", build_s},
          {"targets", targets.size()},
          {"targets_localized", localized},
          {"median_localized_at", median_localized_at(localized_at)},
          {"confident_wrong", wrong},
          {"ms_per_scan_wall", 1e3 * wall_s / scans},
          {"ms_per_scan_cpu_all_workers", 1e3 * cpu_s / scans},
          {"us_per_scan_merge", 1e6 * merge_s / scans},
          {"rss_mb", rss_mb()},
          {"per_target", per_target}};
}

}  // namespace

void add_bench_shards_command(CLI::App& bench, GlobalOptions& global) {
  auto opt = std::make_shared<ShardsOptions>();
  auto* cmd = bench.add_subcommand(
      "shards",
      "The scale-out design measured (docs/scale-out.md): R synthetic buildings split by submap over K\n"
      "workers (submap k to worker k mod K), each with its own map and localizer on its own thread; every\n"
      "target scan goes to all workers and a router merges their reports (best mean score; its margin\n"
      "re-judged against every other worker's best). Prints one JSON line per K: targets localized, when,\n"
      "confident-but-wrong scans, wall and CPU per scan, and the merge's cost.");
  cmd->add_option("--submaps", opt->submaps, "R: synthetic buildings in the whole map")
      ->capture_default_str()
      ->check(within(1, 1000));
  cmd->add_option("--shards", opt->shards, "K values, comma-separated")
      ->delimiter(',')
      ->capture_default_str()
      ->check(within(1, 64));
  cmd->add_option("--targets", opt->targets, "targets, one in each of the first buildings")
      ->capture_default_str()
      ->check(within(1, 1000));
  cmd->add_option("--map-scans", opt->world.map_scans, "scans each mapper robot records")
      ->capture_default_str()
      ->check(within(1, 1e6));
  cmd->add_option("--target-scans", opt->world.target_scans, "scans of each target's run")
      ->capture_default_str()
      ->check(within(1, 1e6));
  cmd->add_option("--seed", opt->world.seed, "world seed")->capture_default_str();
  add_localizer_options(*cmd, opt->localizer);
  cmd->callback([opt, &global] {
    (void)global;
    if (print_config_if_asked(opt->localizer)) return;
    if (opt->targets > opt->submaps) throw Error("bench shards: --targets must not exceed --submaps");
    const bool tty = isatty(fileno(stderr));
    for (const std::size_t k : opt->shards) {
      if (k > opt->submaps) throw Error("bench shards: K = " + std::to_string(k) + " is more than --submaps");
      std::printf("%s\n", io::json_text(run_sharded(*opt, k, tty)).c_str());
      std::fflush(stdout);
    }
  });
}

}  // namespace lshloc::app
