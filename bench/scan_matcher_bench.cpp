// Scans per second of the local-map scan matcher on one core: simulated
// 360-beam scans of a room (tests' ray caster), and, when the shared data is
// present, the first 1000 scans of fr079.
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <numbers>

#include "../tests/laser_sim.hpp"
#include "lshloc/slam/scan_matcher.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/eval/dataset_catalog.hpp"

namespace {

using lshloc::Pose2;

/// A loop around the room's pillar: scans keep coming from new poses, so
/// every one is matched (none is skipped as stationary).
std::vector<lshloc::LaserScan> room_scans(std::size_t count) {
  lshloc::test::LaserSim sim(lshloc::test::test_room());
  std::vector<lshloc::LaserScan> scans;
  for (std::size_t i = 0; i < count; ++i) {
    const double a = 2.0 * std::numbers::pi * static_cast<double>(i) / 200.0;
    const Pose2 p(6.3 + 3.0 * std::cos(a), 3.3 + 2.0 * std::sin(a), a + std::numbers::pi / 2.0);
    scans.push_back(sim.scan(p, p * Pose2(0.01, 0.0, 0.002), 0.1 * static_cast<double>(i)));
  }
  return scans;
}

void BM_ScanMatcherRoom360(benchmark::State& state) {
  const auto scans = room_scans(400);
  std::size_t processed = 0;
  for (auto _ : state) {
    state.PauseTiming();
    lshloc::ScanMatcher matcher;
    state.ResumeTiming();
    for (const auto& s : scans) benchmark::DoNotOptimize(matcher.add_scan(s));
    processed += scans.size();
  }
  state.counters["scans_per_s"] = benchmark::Counter(static_cast<double>(processed), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ScanMatcherRoom360)->Unit(benchmark::kMillisecond);

void BM_ScanMatcherFr079(benchmark::State& state) {
  const std::string dir = lshloc::io::DatasetCatalog::resolve_data_dir("", LSHLOC_SOURCE_DIR "/../shared/data");
  const std::string log = dir + "/fr079/fr079.recon-from-bag.log.gz";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(log, ec)) {
    state.SkipWithError("fr079 raw log not found (set LSHLOC_DATA)");
    return;
  }
  auto scans = lshloc::io::read_carmen_log(log).scans;
  scans.resize(std::min<std::size_t>(scans.size(), 1000));
  std::size_t processed = 0;
  for (auto _ : state) {
    lshloc::ScanMatcher matcher;
    for (const auto& s : scans) benchmark::DoNotOptimize(matcher.add_scan(s));
    processed += scans.size();
  }
  state.counters["scans_per_s"] = benchmark::Counter(static_cast<double>(processed), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ScanMatcherFr079)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
