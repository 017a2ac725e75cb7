#pragma once
// The process's own memory, as the benchmarks report it.
#include <fstream>
#include <sstream>
#include <string>

namespace lshloc::app {

/// A "Name:  N kB" field of a /proc file [MB], or -1 where it cannot be read.
inline double proc_field_mb(const char* path, const std::string& name) {
  std::ifstream file(path);
  std::string line;
  while (std::getline(file, line)) {
    if (line.rfind(name, 0) == 0) {
      std::istringstream in(line.substr(name.size()));
      double kb = 0;
      in >> kb;
      return kb / 1024.0;
    }
  }
  return -1.0;
}

/// Resident set size of this process [MB] (Linux /proc/self/status), or -1
/// where it cannot be read.
inline double rss_mb() { return proc_field_mb("/proc/self/status", "VmRSS:"); }

/// Of it, anonymous memory on transparent huge pages [MB]: the map's tables
/// are allocated for them (common/huge_page_allocator.hpp), and random reads
/// slow down where the kernel did not give them.
inline double huge_pages_mb() { return proc_field_mb("/proc/self/smaps_rollup", "AnonHugePages:"); }

}  // namespace lshloc::app
