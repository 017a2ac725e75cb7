// LshDatabase kernels: insert and query per feature at growing sizes, on
// clustered synthetic unit descriptors (fixed seed). The peer comparison on
// real descriptors is bench/lsh_peers_bench.cpp.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "lshloc/appearance/lsh_database.hpp"

namespace {

std::vector<lshloc::Descriptor> descriptors(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<lshloc::Descriptor> centres(std::max<std::size_t>(n / 5, 1));
  for (auto& c : centres)
    for (float& v : c) v = g(rng);
  std::vector<lshloc::Descriptor> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    double norm = 0;
    for (std::size_t j = 0; j < lshloc::kDescriptorSize; ++j) {
      out[i][j] = centres[i % centres.size()][j] + 0.3f * g(rng);
      norm += double(out[i][j]) * out[i][j];
    }
    for (float& v : out[i]) v = static_cast<float>(v / std::sqrt(norm));
  }
  return out;
}

/// Insert then query on a database of state.range(0) entries.
void BM_LshInsert(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto data = descriptors(n + 4096, 1);
  lshloc::LshDatabase db;
  for (std::size_t i = 0; i < n; ++i) db.insert(data[i], static_cast<std::uint32_t>(i));
  std::size_t i = n;
  for (auto _ : state) {
    db.insert(data[i], static_cast<std::uint32_t>(i));
    if (++i == data.size()) i = n;
  }
  state.counters["bytes_per_entry"] = db.stats().bytes_per_entry();
}

void BM_LshQuery(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto data = descriptors(n, 1);
  const auto queries = descriptors(4096, 2);
  lshloc::LshDatabase db;
  for (std::size_t i = 0; i < n; ++i) db.insert(data[i], static_cast<std::uint32_t>(i));
  lshloc::LshQuery q(db);
  std::vector<std::uint32_t> out;
  std::size_t i = 0;
  for (auto _ : state) {
    db.query(data[(i * 7919) % n], 100, out, q);
    benchmark::DoNotOptimize(out.data());
    ++i;
  }
  state.counters["candidates"] = double(q.candidates_touched) / double(q.queries);
}

}  // namespace

BENCHMARK(BM_LshInsert)->Arg(10000)->Arg(100000)->Arg(1000000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_LshQuery)->Arg(10000)->Arg(100000)->Arg(1000000)->Unit(benchmark::kMicrosecond);
BENCHMARK_MAIN();
