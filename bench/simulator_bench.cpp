// Simulator speed: ray casting per scan, whole recordings (scans/s), floor
// plan generation, and the cost of a scan as buildings grow (the bucketing
// grid should keep it flat).
#include <benchmark/benchmark.h>

#include <random>

#include "lshloc/sim/simulator.hpp"

namespace lshloc::sim {
namespace {

SyntheticBuilding building(double size, std::uint64_t seed = 1) {
  BuildingGeneratorConfig config;
  config.plan.seed = seed;
  config.plan.min_size = config.plan.max_size = size;
  return generate_building(config);
}

/// Casts one 180-beam scan per iteration from poses along a recorded tour of `b` (noise included).
void cast_scans(benchmark::State& state, const SyntheticBuilding& b) {
  const Trajectory tour = drive_tour(b.plan, {}, 2000, 5);
  LaserConfig laser;
  LaserScan scan;
  set_beam_layout(laser, scan);
  std::mt19937_64 rng(1);
  std::size_t k = 0;
  for (auto _ : state) {
    simulate_ranges(b.caster, tour.poses[k++ % tour.poses.size()], laser, rng, scan);
    benchmark::DoNotOptimize(scan.ranges.data());
  }
  state.SetItemsProcessed(state.iterations());  // scans
}

/// One 180-beam scan from poses along a recorded tour (noise included).
void BM_CastScan(benchmark::State& state) {
  const auto b = building(static_cast<double>(state.range(0)));
  cast_scans(state, b);
  state.counters["segments"] = static_cast<double>(b.plan.segments.size());
}
BENCHMARK(BM_CastScan)->Arg(30)->Arg(80)->Arg(200)->Arg(400);

/// The bucket size: one 180-beam scan in a 60 m building, cell = arg / 10 m.
void BM_CastScanCell(benchmark::State& state) {
  BuildingGeneratorConfig config;
  config.plan.min_size = config.plan.max_size = 60.0;
  config.caster.cell = static_cast<double>(state.range(0)) / 10.0;
  const auto b = generate_building(config);
  cast_scans(state, b);
  state.counters["bucket_entries"] = static_cast<double>(b.caster.bucket_entries());
}
BENCHMARK(BM_CastScanCell)->Arg(3)->Arg(5)->Arg(10)->Arg(20)->Arg(40);

/// A whole recording of 2000 scans (tour, odometry, laser; raw + corrected).
void BM_SimulateRecording(benchmark::State& state) {
  const auto b = building(60.0);
  SimulationConfig config;
  config.scans = 2000;
  for (auto _ : state) {
    auto rec = simulate_recording(b, config);
    benchmark::DoNotOptimize(rec.raw_scans.data());
    ++config.seed;
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(config.scans));  // scans
}
BENCHMARK(BM_SimulateRecording)->Unit(benchmark::kMillisecond);

/// Floor plan, clearance grid and ray-caster buckets of one building.
void BM_GenerateBuilding(benchmark::State& state) {
  std::uint64_t seed = 1;
  for (auto _ : state) {
    auto b = building(static_cast<double>(state.range(0)), seed++);
    benchmark::DoNotOptimize(b.plan.segments.data());
  }
}
BENCHMARK(BM_GenerateBuilding)->Arg(30)->Arg(80)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace lshloc::sim

BENCHMARK_MAIN();
