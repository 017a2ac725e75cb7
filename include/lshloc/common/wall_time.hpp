#pragma once
// Wall-clock durations, for what a user waits on (map building, whole runs);
// per-stage costs use CPU time (cpu_time.hpp).
// Thread safety: safe from any thread.
#include <chrono>

namespace lshloc {

/// [s] wall-clock time since `t` (steady clock).
inline double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace lshloc
