// `lshloc info LOG...`: one JSON line per CARMEN log (scan and odometry counts,
// beam counts, duration); `lshloc info --buildings`: the data directory's
// buildings and their files, one JSON line each (scripts read it).
#include <cstdio>
#include <filesystem>
#include <set>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/io/carmen_reader.hpp"
#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/io/config_json.hpp"
#include "map_source.hpp"

namespace lshloc::app {

namespace {

nlohmann::json summarize_log(const std::string& path) {
  io::CarmenReader reader(path);
  io::CarmenRecord rec;
  std::size_t scans = 0, odometry = 0, params = 0;
  std::set<std::size_t> beams;
  // Duration from scan stamps where there are scans: corrected logs often
  // carry placeholder odometry stamps.
  struct Span {
    double lo = 0.0, hi = 0.0;
    bool any = false;
    void add(double t) {
      if (!any) lo = hi = t, any = true;
      lo = std::min(lo, t), hi = std::max(hi, t);
    }
    double length() const { return any ? hi - lo : 0.0; }
  } scan_span, odom_span;
  while (reader.next(rec)) {
    switch (rec.type) {
      case io::CarmenRecord::Type::kLaser:
        ++scans, beams.insert(rec.scan.size()), scan_span.add(rec.scan.timestamp);
        break;
      case io::CarmenRecord::Type::kOdometry:
        ++odometry, odom_span.add(rec.odometry.timestamp);
        break;
      case io::CarmenRecord::Type::kParam:
        ++params;
        break;
    }
  }
  reader.require_messages();
  const std::vector<std::string> warnings = reader.warnings();
  print_warnings(warnings);
  return {{"file", path},         {"scans", scans},
          {"odometry", odometry}, {"beams", beams},
          {"params", params},     {"duration_s", scans > 1 ? scan_span.length() : odom_span.length()},
          {"warnings", warnings}};
}

nlohmann::json building_files(const io::BuildingFiles& b) {
  const auto path = [](const std::string& p) {
    std::error_code ec;
    return p.empty() || !std::filesystem::is_regular_file(p, ec) ? nlohmann::json() : nlohmann::json(p);
  };
  return {{"building", b.name},
          {"raw_log", path(b.raw_log)},
          {"corrected_log", path(b.corrected_log)},
          {"poses", path(b.poses)},
          {"relations", path(b.relations)},
          {"laser_offset_x_m", b.laser_offset_x ? nlohmann::json(*b.laser_offset_x) : nlohmann::json()}};
}

}  // namespace

void add_info_command(CLI::App& app, GlobalOptions& global) {
  auto* cmd = app.add_subcommand("info",
                                 "Summarize CARMEN logs: one JSON line per log with its scan count (FLASER +\n"
                                 "ROBOTLASER1), odometry count (ODOM), distinct beam counts and duration.\n"
                                 "With no LOG, every log of the data directory is summarized.");
  auto logs = std::make_shared<std::vector<std::string>>();
  auto buildings = std::make_shared<bool>(false);
  cmd->add_option("LOG", *logs, "CARMEN log files, plain or .gz");
  cmd->add_flag("--buildings", *buildings,
                "list the data directory's buildings instead: one JSON line each with the paths of its raw log, "
                "corrected log, ground-truth poses and relations (null where it has none on disk)")
      ->excludes("LOG");
  cmd->callback([&global, logs, buildings] {
    if (*buildings) {
      const io::DatasetCatalog catalog(global.resolved_data_dir());
      for (const io::BuildingFiles& b : catalog.buildings())
        std::printf("%s\n", io::json_text(building_files(b)).c_str());
      if (catalog.existing_logs().empty())
        std::fprintf(stderr,
                     "lshloc: warning: %s holds none of the buildings' logs (../shared/data/README.md names them); "
                     "give the data directory with --data DIR or LSHLOC_DATA\n",
                     catalog.data_dir().c_str());
      return;
    }
    std::vector<std::string> files = *logs;
    if (files.empty()) {
      const io::DatasetCatalog catalog(global.resolved_data_dir());
      files = catalog.existing_logs();
      if (files.empty()) throw Error("no logs found in data directory " + catalog.data_dir());
    }
    for (const auto& f : files) {
      try {
        std::printf("%s\n", io::json_text(summarize_log(f)).c_str());
        std::fflush(stdout);
      } catch (const Error& e) {
        std::fprintf(stderr, "lshloc: error: %s\n", e.what());
        global.exit_code = 1;
      }
    }
  });
}

}  // namespace lshloc::app
