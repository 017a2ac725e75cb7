#pragma once
// The process's own memory, as the benchmarks report it.
#include <fstream>
#include <sstream>
#include <string>

namespace lshloc::app {

/// Resident set size of this process [MB] (Linux /proc/self/status), or -1
/// where it cannot be read.
inline double rss_mb() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) {
      std::istringstream in(line.substr(6));
      double kb = 0;
      in >> kb;
      return kb / 1024.0;
    }
  }
  return -1.0;
}

}  // namespace lshloc::app
