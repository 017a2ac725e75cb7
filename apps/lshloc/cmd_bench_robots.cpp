// `lshloc bench robots`: many localizing robots on one shared global map.
// One process builds a scenario's map once; then, for each thread count T,
// T robots localize the scenario's target window at the same time, each on
// its own thread with its own Localizer, all reading the one map. Thread
// counts alternate over rounds (the machine is noisy); each row reports the
// median throughput and the memory of the process while the robots ran.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "localizer_options.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/io/config_json.hpp"
#include "option_checks.hpp"
#include "process_memory.hpp"

namespace lshloc::app {

namespace {

struct RobotsOptions {
  ScenarioConfig scenario{.submaps = 15};
  std::vector<std::size_t> threads{1, 2};
  std::size_t rounds = 3;
  bool json = false;
  LocalizerOptions localizer;
};

/// One round at one thread count: wall time, the peak resident memory seen
/// while the robots ran, and each robot's run.
struct RoundResult {
  double wall_s = 0.0;
  double peak_rss_mb = 0.0;
  std::vector<LocalizationRun> runs;
};

RoundResult run_robots(const GlobalMap& map, const TargetRun& target, const LocalizerConfig& config,
                       std::size_t threads) {
  RoundResult r;
  r.runs.resize(threads);
  std::atomic<std::size_t> running{threads};
  const auto t0 = std::chrono::steady_clock::now();
  {
    std::vector<std::jthread> robots;
    for (std::size_t i = 0; i < threads; ++i)
      robots.emplace_back([&, i] {
        r.runs[i] = localize_target(map, target, config);
        --running;
      });
    // This thread only watches memory while the robots run.
    while (running.load() > 0) {
      r.peak_rss_mb = std::max(r.peak_rss_mb, rss_mb());
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  r.wall_s = seconds_since(t0);
  r.peak_rss_mb = std::max(r.peak_rss_mb, rss_mb());
  return r;
}

/// Whether two runs gave the same estimate at every scan, bit for bit.
bool same_estimates(const LocalizationRun& a, const LocalizationRun& b) {
  if (a.estimates.size() != b.estimates.size()) return false;
  for (std::size_t i = 0; i < a.estimates.size(); ++i) {
    const auto &x = a.estimates[i], &y = b.estimates[i];
    if (x.has_estimate != y.has_estimate || x.localized != y.localized || x.submap != y.submap ||
        x.pose.x != y.pose.x || x.pose.y != y.pose.y || x.pose.theta != y.pose.theta)
      return false;
  }
  return true;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace

void add_bench_robots_command(CLI::App& bench, GlobalOptions& global) {
  auto opt = std::make_shared<RobotsOptions>();
  auto* cmd = bench.add_subcommand(
      "robots",
      "Several localizing robots on one shared global map: builds a scenario's map once (default: fr079's\n"
      "default window, R = 15 submaps), then for each --threads count T runs T robots at once, each\n"
      "localizing the target window on its own thread against the one map. Thread counts alternate over\n"
      "--rounds. Prints one JSON line per thread count: target scans/s of all robots together (median over\n"
      "rounds), the process's resident memory while they ran (rss_mb, from the first round, where the\n"
      "counts run in ascending order), what one map per robot would take instead, and whether every\n"
      "robot's estimates equal a lone robot's.");
  cmd->add_option("--building", opt->scenario.building, "target building (a directory of the data directory)")
      ->capture_default_str();
  cmd->add_option("--start", opt->scenario.start, "first raw scan of the target window (default: the building's)");
  cmd->add_option("--length", opt->scenario.length, "raw scans in the target window")
      ->capture_default_str()
      ->check(within(1, 1e6));
  cmd->add_option("--submaps", opt->scenario.submaps, "R: the target's building plus R-1 others")
      ->capture_default_str()
      ->check(within(1, 15));
  cmd->add_option("--threads", opt->threads, "thread counts (robots at once), comma-separated")
      ->delimiter(',')
      ->capture_default_str()
      ->check(within(1, 256));
  cmd->add_option("--rounds", opt->rounds, "rounds over the thread counts (alternating); medians are reported")
      ->capture_default_str()
      ->check(within(1, 100));
  cmd->add_flag("--json", opt->json, "JSON lines only (the default output is JSON lines too)");
  add_localizer_options(*cmd, opt->localizer);
  cmd->callback([opt, cmd, &global] {
    if (print_config_if_asked(opt->localizer)) return;
    if (cmd->count("--start") == 0) opt->scenario.start = default_window_start(opt->scenario.building);
    const bool tty = isatty(fileno(stderr));
    const io::DatasetCatalog catalog(global.resolved_data_dir());
    const Scenario sc = io::load_scenario(catalog, opt->scenario);
    const RunConfig config = make_run_config(opt->localizer);
    GlobalMap map(config.map);
    MapFeeder(map, sc.submaps).feed_until(1.0);
    const double map_rss_mb = rss_mb();
    const LocalizerConfig localizer = with_target_laser_offset(config.localizer, sc.target.laser_offset);
    if (tty) std::fprintf(stderr, "map: %zu submaps, %zu features\n", map.submap_count(), map.stats().features);

    // A lone robot's run is the reference every robot must equal.
    const LocalizationRun reference = localize_target(map, sc.target, localizer);
    std::vector<std::vector<double>> scans_per_s(opt->threads.size());
    std::vector<double> first_rss(opt->threads.size(), 0.0), cpu_s(opt->threads.size(), 0.0);
    std::vector<bool> identical(opt->threads.size(), true);
    const double scans = static_cast<double>(sc.target.scans.size());
    for (std::size_t round = 0; round < opt->rounds; ++round) {
      // Ascending in even rounds, descending in odd ones.
      for (std::size_t n = 0; n < opt->threads.size(); ++n) {
        const std::size_t k = round % 2 == 0 ? n : opt->threads.size() - 1 - n;
        const std::size_t t = opt->threads[k];
        if (tty) std::fprintf(stderr, "\rround %zu/%zu: %zu robots   ", round + 1, opt->rounds, t);
        const RoundResult r = run_robots(map, sc.target, localizer, t);
        scans_per_s[k].push_back(scans * static_cast<double>(t) / r.wall_s);
        if (round == 0) first_rss[k] = r.peak_rss_mb;
        for (const auto& run : r.runs) {
          identical[k] = identical[k] && same_estimates(run, reference);
          cpu_s[k] += run.localize_cpu_s;
        }
      }
    }
    if (tty) std::fprintf(stderr, "\n");
    const auto one = std::find(opt->threads.begin(), opt->threads.end(), std::size_t{1});
    const double lone_rss =
        one != opt->threads.end() ? first_rss[static_cast<std::size_t>(one - opt->threads.begin())] : map_rss_mb;
    for (std::size_t k = 0; k < opt->threads.size(); ++k) {
      const auto t = static_cast<double>(opt->threads[k]);
      nlohmann::json j;
      j["building"] = opt->scenario.building;
      j["submaps"] = sc.submaps.size();
      j["map_features"] = map.stats().features;
      j["target_scans"] = sc.target.scans.size();
      j["threads"] = opt->threads[k];
      j["rounds"] = opt->rounds;
      j["scans_per_s"] = median(scans_per_s[k]);
      j["scans_per_s_rounds"] = scans_per_s[k];
      j["cpu_ms_per_scan"] = 1e3 * cpu_s[k] / (scans * t * static_cast<double>(opt->rounds));
      j["rss_mb"] = first_rss[k];
      j["map_rss_mb"] = map_rss_mb;
      j["rss_mb_one_map_per_robot"] = lone_rss * t;
      j["hardware_threads"] = std::thread::hardware_concurrency();
      j["estimates_identical"] = static_cast<bool>(identical[k]);
      std::printf("%s\n", io::json_text(j).c_str());
      std::fflush(stdout);
    }
  });
}

}  // namespace lshloc::app
