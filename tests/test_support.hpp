#pragma once
#include <numbers>
#include <optional>
#include <string>

#include <vector>

#include "lshloc/localization/global_map.hpp"
#include "lshloc/sim/synthetic_scenario.hpp"

namespace lshloc::test {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kDeg = kPi / 180.0;

/// The shared data directory if it exists ($LSHLOC_DATA, else ../shared/data
/// beside the source tree), or nullopt: tests that need real logs skip then.
std::optional<std::string> data_dir();

/// A map's snapshot without the build's CPU times (the only part two builds
/// of one map may differ in).
std::vector<MapSection> map_contents(const GlobalMap& map);
/// Expects two maps to hold the same contents, section by section.
void expect_same_map_contents(const GlobalMap& a, const GlobalMap& b);

/// A fresh temporary file path with the given suffix, in a folder of this
/// process's own that is removed when the process exits normally.
std::string temp_path(const std::string& suffix);

/// Three synthetic buildings (seed 11), the target touring building 1: the
/// small world the end-to-end tests localize in.
sim::SyntheticScenarioConfig small_world(std::size_t map_scans = 900, std::size_t target_scans = 300);

/// The bytes of the file at `path` (empty when it cannot be read).
std::string read_file(const std::string& path);

/// Writes `text` to `path`, gzip-compressed when the path ends in .gz.
void write_file(const std::string& path, const std::string& text);

}  // namespace lshloc::test

#define LSHLOC_REQUIRE_DATA(dir)                                                                \
  const auto dir##_opt = ::lshloc::test::data_dir();                                            \
  if (!dir##_opt) GTEST_SKIP() << "shared data directory not found (set LSHLOC_DATA); skipped"; \
  const std::string dir = *dir##_opt
