// `lshloc map`: build a global map once and keep it (docs/map-format.md):
// build, append, info, verify, compact.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <shared_mutex>
#include <thread>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "lshloc/common/cpu_time.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/fleet/map_follower.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/map_store.hpp"
#include "lshloc/io/ros_map.hpp"
#include "lshloc/slam/occupancy_grid.hpp"
#include "map_source.hpp"
#include "option_checks.hpp"

namespace lshloc::app {

namespace {

std::uint64_t file_bytes(const std::string& path) {
  std::error_code ec;
  const auto n = std::filesystem::file_size(path, ec);
  return ec ? 0 : static_cast<std::uint64_t>(n);
}

/// The map's contents and its file, as `map info --json` prints them.
nlohmann::json map_json(const std::string& path, const GlobalMap& map, const io::MapFileInfo& info) {
  const GlobalMapStats s = map.stats();
  nlohmann::json j;
  j["path"] = path;
  j["format_version"] = info.format_version;
  j["bytes"] = info.file_bytes;
  j["snapshot_bytes"] = info.snapshot_bytes;
  j["journal_bytes"] = info.journal_bytes;
  j["journal_submaps"] = info.journal_submaps;
  j["journal_scans"] = info.journal_scans;
  j["torn_bytes"] = info.torn_bytes;
  j["submaps"] = map.submap_count();
  j["scans"] = s.scans;
  j["features"] = s.features;
  j["file_bytes_per_feature"] =
      s.features ? static_cast<double>(info.file_bytes) / static_cast<double>(s.features) : 0.0;
  j["memory_bytes_per_feature"] = s.bytes_per_feature();
  // CPU seconds of every insert so far, by stage (a saved map carries them): where ingest time goes.
  j["insert_cpu_s"] = {{"features", s.extract_s}, {"database", s.database_insert_s}, {"grids", s.grid_s}};
  nlohmann::json submaps = nlohmann::json::array();
  for (std::uint32_t i = 0; i < map.submap_count(); ++i)
    submaps.push_back({{"id", i}, {"name", map.submap_name(i)}, {"scans", map.submap_scans(i)}});
  j["submap_list"] = submaps;
  nlohmann::json sections = nlohmann::json::array();
  for (const auto& sec : info.sections) sections.push_back({{"name", sec.name}, {"bytes", sec.bytes}});
  j["sections"] = sections;
  j["settings"] = map.config();
  j["meta"] = info.meta;
  return j;
}

struct BuildOptions {
  std::vector<std::string> logs;
  std::vector<std::string> names;
  std::string out;
  std::string config;
  bool slam = false;
  bool json = false;
  bool print_config = false;
  GridMapOptions grid;
};

struct AppendOptions {
  std::string map;
  std::string log;
  std::string submap;
  std::size_t from = 0;
  std::size_t count = 0;
  std::size_t sync_every = 1;
  bool slam = false;
  bool ack_lines = false;
  bool json = false;
};

GlobalMapConfig map_settings(const std::string& config_path) try {
  GlobalMapConfig c;
  if (config_path.empty()) return c;
  nlohmann::json settings = io::read_json_file(config_path);
  // The shape localize and eval take ({"map": ..., "localizer": ...}) gives its map part: one file serves both.
  if (settings.is_object() && settings.contains("map")) {
    if (settings.size() > 1)
      std::fprintf(stderr,
                   "lshloc: warning: %s: a map takes only the \"map\" settings; the others are for "
                   "localize and eval\n",
                   config_path.c_str());
    nlohmann::json map_part = settings["map"];
    settings = std::move(map_part);
  }
  io::apply_config_patch(settings, c, config_path);
  c.validate();
  return c;
} catch (const Error& e) {
  if (std::string(e.what()).starts_with(config_path)) throw;
  throw Error(config_path + ": " + e.what());
}

/// The options `map build` and `map from-grid` share; returns --out (needed
/// unless --print-config: require_given()).
const CLI::Option* add_build_options(CLI::App& cmd, BuildOptions& opt, bool from_grid) {
  const CLI::Option* out = cmd.add_option("--out", opt.out, "the map file to write (required)");
  // One name per --name (repeat it): a list would swallow the map arguments after it.
  cmd.add_option("--name", opt.names,
                 "a submap name; repeat it, one per map argument in order (default: each file's name)")
      ->expected(1)
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cmd.add_option("--config", opt.config,
                 "JSON file of map settings: GlobalMapConfig fields (the shape --print-config writes), or the "
                 "{\"map\": ...} part of a localize/eval config (examples/config/)");
  cmd.add_flag("--print-config", opt.print_config, "print the effective map settings as JSON and exit");
  cmd.add_flag("--json", opt.json, "print one JSON line (the fields of `map info --json`) instead of text");
  // map build takes the robot's laser for ROS grids; the lattice and an explicit laser are from-grid's.
  add_grid_map_options(cmd, opt.grid, /*laser_of_only=*/!from_grid);
  return out;
}

void run_build(const BuildOptions& opt, const char* made_by) {
  const GlobalMapConfig config = map_settings(opt.config);
  if (opt.print_config) {
    std::printf("%s\n", io::json_text(nlohmann::json(config), 2).c_str());
    return;
  }
  io::require_replaceable(opt.out);  // before the work, not after it
  const auto t0 = std::chrono::steady_clock::now();
  GlobalMap map(config);
  std::fprintf(stderr, "%s: reading and adding %zu submaps\n", made_by, opt.logs.size());
  const io::MapSources built = add_map_arguments(map, opt.logs, opt.slam, opt.grid.resolve(nullptr), opt.names);
  nlohmann::json sources = nlohmann::json::array();
  for (std::uint32_t id = 0; id < map.submap_count(); ++id) {
    nlohmann::json s = {{"submap", map.submap_name(id)}, {"source", opt.logs[id]}};
    for (std::size_t i = 0; i < built.log_ids.size(); ++i)
      if (built.log_ids[i] == id)
        s["scans"] = built.logs[i].scans.size(), s["poses_from_slam"] = built.logs[i].poses_from_slam;
    for (std::size_t i = 0; i < built.grid_ids.size(); ++i)
      if (built.grid_ids[i] == id) s["virtual_scans"] = built.grid_stats[i].virtual_scans;
    sources.push_back(s);
  }
  const double build_s = seconds_since(t0);
  const auto t1 = std::chrono::steady_clock::now();
  io::save_map(opt.out, map, {{"made_by", made_by}, {"submaps", sources}});
  const double save_s = seconds_since(t1);
  const io::LoadedMap check = io::load_map(opt.out);  // what was written reads back
  nlohmann::json j = map_json(opt.out, *check.map, check.info);
  j["build_s"] = build_s;
  j["save_s"] = save_s;
  if (opt.json) {
    std::printf("%s\n", io::json_text(j).c_str());
  } else {
    std::printf(
        "%s: %zu submaps, %zu scans, %zu features, %llu bytes (%.1f per feature); built in %.1f s, saved in "
        "%.2f s\n",
        opt.out.c_str(), map.submap_count(), map.stats().scans, map.stats().features,
        static_cast<unsigned long long>(check.info.file_bytes), j["file_bytes_per_feature"].get<double>(), build_s,
        save_s);
  }
}

void add_build(CLI::App& map_cmd) {
  auto opt = std::make_shared<BuildOptions>();
  auto* cmd = map_cmd.add_subcommand(
      "build",
      "Build a global map from mapped logs, one submap per log, and save it (an atomic write: the file holds\n"
      "the old map or the whole new one). LOG takes the log's own FLASER poses (a corrected log; with --slam, a\n"
      "raw log posed by lshloc's SLAM); LOG,slam poses that raw log by SLAM; LOG,POSES takes poses from a\n"
      "`timestamp x y theta` file; MAP.yaml builds a submap from a ROS occupancy grid (see `map from-grid`).");
  const CLI::Option* logs = cmd->add_option(
      "logs", opt->logs,
      "map logs: LOG, LOG,POSES or LOG,slam (this raw log posed by lshloc's SLAM), or ROS maps MAP.yaml (required)");
  cmd->add_flag("--slam", opt->slam, "pose raw logs given without a poses file by lshloc's SLAM");
  const CLI::Option* out = add_build_options(*cmd, *opt, false);
  cmd->callback([opt, logs, out] {
    if (!opt->print_config) require_given({logs, out});
    run_build(*opt, "lshloc map build");
  });
}

void add_from_grid(CLI::App& map_cmd) {
  auto opt = std::make_shared<BuildOptions>();
  auto* cmd = map_cmd.add_subcommand(
      "from-grid",
      "Build a global map from ROS occupancy grids (map_server's MAP.yaml + its PGM or PNG: resolution, origin,\n"
      "thresholds, negate, mode), one submap per grid, and save it. Virtual laser scans ray-cast from free\n"
      "positions (a lattice, several headings each) fill the appearance database; the occupied cells, with\n"
      "their surface normals, fill the pose grid and the free cells the free-space grid. The virtual laser\n"
      "should match the robot's that will localize (--grid-beams, --grid-fov-deg, --grid-max-range).\n"
      "`localize --map MAP.yaml` builds the same submap on the fly with the target's laser.");
  const CLI::Option* grids = cmd->add_option("grids", opt->logs, "ROS map YAML files (required)");
  const CLI::Option* out = add_build_options(*cmd, *opt, true);
  cmd->callback([opt, grids, out] {
    if (!opt->print_config) require_given({grids, out});
    for (const std::string& g : opt->logs)
      if (!io::is_ros_map_path(g)) throw Error(g + ": expected a ROS map YAML (.yaml/.yml); logs go to `map build`");
    run_build(*opt, "lshloc map from-grid");
  });
}

void add_append(CLI::App& map_cmd) {
  auto opt = std::make_shared<AppendOptions>();
  auto* cmd = map_cmd.add_subcommand(
      "append",
      "Append a mapped log's scans to a saved map's journal, as a new submap or onto an existing one (--submap\n"
      "NAME of a submap the map has: the poses must be in its frame). Each scan is acknowledged once its journal\n"
      "record is fsync'ed (every --sync-every scans); a crash loses no acknowledged scan.");
  cmd->add_option("map", opt->map, "the map file")->required();
  cmd->add_option("log", opt->log, "LOG, LOG,POSES or LOG,slam, as for `map build`")->required();
  cmd->add_option("--submap", opt->submap,
                  "submap to add to, made when the map has none of that name (default: the log's file name)");
  cmd->add_option("--from", opt->from, "first scan of the log to append (to resume an interrupted append)")
      ->capture_default_str();
  cmd->add_option("--count", opt->count, "scans to append (0: to the end of the log)")->capture_default_str();
  cmd->add_option("--sync-every", opt->sync_every, "scans per fsync (1: each scan is durable before the next)")
      ->capture_default_str()
      ->check(within(1, 1e9));
  cmd->add_flag("--slam", opt->slam, "pose a raw log given without a poses file by lshloc's SLAM");
  cmd->add_flag("--ack-lines", opt->ack_lines,
                "after each fsync print `acknowledged N` (N: the submap's durable scans) on stdout, flushed");
  cmd->add_flag("--json", opt->json, "print one JSON summary line");
  cmd->callback([opt] {
    const Submap log = load_map_argument(opt->log, opt->slam);
    if (opt->from > log.scans.size())
      throw Error(opt->log + ": --from " + std::to_string(opt->from) + " is past its " +
                  std::to_string(log.scans.size()) + " posed scans");
    io::MapAppender appender(opt->map, {.sync_every = opt->sync_every});
    print_warnings(appender.warnings());
    const std::string name = opt->submap.empty() ? log.name : opt->submap;
    const auto existing = appender.map().find_submap(name);
    const std::uint32_t submap = existing ? *existing : appender.add_submap(name);
    const std::size_t submap_before = appender.map().submap_scans(submap);
    // The submap named after this log holds its first scans already: appending them again would map each twice.
    if (opt->submap.empty() && existing && opt->from < submap_before)
      throw Error(opt->map + ": submap " + name + " holds " + std::to_string(submap_before) +
                  " scans of this log already; --from " + std::to_string(submap_before) +
                  " resumes after them, --submap NAME adds the log as another submap");
    const std::size_t acked_before = appender.acknowledged_scans();
    const std::size_t end = opt->count == 0 ? log.scans.size() : std::min(log.scans.size(), opt->from + opt->count);
    const bool tty = isatty(fileno(stderr));
    std::size_t last_acked = acked_before;
    const auto t0 = std::chrono::steady_clock::now();
    const auto report = [&] {
      if (opt->ack_lines && appender.acknowledged_scans() != last_acked) {
        last_acked = appender.acknowledged_scans();
        std::printf("acknowledged %zu\n", submap_before + (last_acked - acked_before));
        std::fflush(stdout);
      }
    };
    std::size_t features = 0;
    for (std::size_t i = opt->from; i < end; ++i) {
      try {
        features += appender.add_scan(submap, log.scans[i], log.scans[i].pose);
      } catch (const Error& e) {
        const std::string file = io::MapSource::parse(opt->log).path;  // LOG of LOG,POSES
        throw Error(file + (log.scans[i].source_line ? ":" + std::to_string(log.scans[i].source_line) : "") + ": " +
                    e.what());
      }
      report();
      if (tty && ((i - opt->from) % 100 == 0 || i + 1 == end))
        std::fprintf(stderr, "\rmap append: scan %zu/%zu", i + 1 - opt->from, end - opt->from);
    }
    appender.sync();
    report();
    if (tty) std::fprintf(stderr, "\n");
    const double seconds = seconds_since(t0);
    const std::size_t appended = end - opt->from;
    nlohmann::json j = {{"map", opt->map},
                        {"submap", name},
                        {"submap_id", submap},
                        {"new_submap", !existing.has_value()},
                        {"appended_scans", appended},
                        {"appended_features", features},
                        {"submap_scans", appender.map().submap_scans(submap)},
                        {"scans", appender.map().stats().scans},
                        {"features", appender.map().stats().features},
                        {"seconds", seconds},
                        {"scans_per_s", seconds > 0 ? static_cast<double>(appended) / seconds : 0.0},
                        {"sync_every", opt->sync_every}};
    if (opt->json) {
      std::printf("%s\n", io::json_text(j).c_str());
    } else if (!opt->ack_lines) {
      // A new submap is said so: a misspelt --submap makes one instead of extending the one meant.
      std::printf("%s: appended %zu scans (%zu features) to %s submap %s in %.2f s (%.0f scans/s)\n", opt->map.c_str(),
                  appended, features, existing ? "the" : "a new", name.c_str(), seconds,
                  j["scans_per_s"].get<double>());
    }
  });
}

void add_info(CLI::App& map_cmd) {
  auto path = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto* cmd = map_cmd.add_subcommand(
      "info", "Describe a saved map: submaps, scans, features, bytes, format version, settings and journal.");
  cmd->add_option("map", *path, "the map file")->required();
  cmd->add_flag("--json", *json, "print one JSON object");
  cmd->callback([path, json] {
    const auto t0 = std::chrono::steady_clock::now();
    const double cpu0 = process_cpu_seconds();
    const io::LoadedMap loaded = io::load_map(*path);
    const double load_cpu_s = process_cpu_seconds() - cpu0;
    const double load_s = seconds_since(t0);
    print_warnings(loaded.warnings);
    nlohmann::json j = map_json(*path, *loaded.map, loaded.info);
    j["load_s"] = load_s;
    j["load_cpu_s"] = load_cpu_s;
    if (*json) {
      std::printf("%s\n", io::json_text(j).c_str());
      return;
    }
    std::printf("%s: lshloc map, format version %u\n", path->c_str(), loaded.info.format_version);
    std::printf("  %zu submaps, %zu scans, %zu features\n", loaded.map->submap_count(), j["scans"].get<std::size_t>(),
                j["features"].get<std::size_t>());
    std::printf("  %llu bytes (%.1f per feature): snapshot %llu, journal %llu (%zu scans, %zu new submaps)\n",
                static_cast<unsigned long long>(loaded.info.file_bytes), j["file_bytes_per_feature"].get<double>(),
                static_cast<unsigned long long>(loaded.info.snapshot_bytes),
                static_cast<unsigned long long>(loaded.info.journal_bytes), loaded.info.journal_scans,
                loaded.info.journal_submaps);
    for (std::uint32_t i = 0; i < loaded.map->submap_count(); ++i)
      std::printf("  submap %u: %s, %zu scans\n", i, loaded.map->submap_name(i).c_str(), loaded.map->submap_scans(i));
    std::printf("  settings and sections: `lshloc map info --json %s`\n", path->c_str());
  });
}

void add_verify(CLI::App& map_cmd) {
  auto path = std::make_shared<std::string>();
  auto* cmd = map_cmd.add_subcommand(
      "verify",
      "Check a saved map: every checksum (header, sections, journal records) and every structure it decodes to.\n"
      "Exit 0 when it is good (a torn last journal record, as a crash leaves it, is reported and is not an error),\n"
      "1 with a message naming the damaged part when not.");
  cmd->add_option("map", *path, "the map file")->required();
  cmd->callback([path] {
    const io::LoadedMap loaded = io::load_map(*path);
    print_warnings(loaded.warnings);
    std::size_t records = loaded.info.journal_scans + loaded.info.journal_submaps;
    std::printf(
        "%s: good: format version %u, %zu sections and %zu journal records checked; %zu submaps, %zu scans, "
        "%zu features\n",
        path->c_str(), loaded.info.format_version, loaded.info.sections.size(), records, loaded.map->submap_count(),
        loaded.map->stats().scans, loaded.map->stats().features);
  });
}

void add_to_grid(CLI::App& map_cmd) {
  struct Options {
    std::string log, out;
    bool slam = false;
    OccupancyGridConfig grid;
  };
  auto opt = std::make_shared<Options>();
  auto* cmd = map_cmd.add_subcommand(
      "to-grid",
      "Write a mapped log's submap as a ROS occupancy grid (map_server's OUT.yaml + OUT.pgm, as AMCL and nav2\n"
      "load): cells where beams ended are occupied, cells they crossed free, the rest unknown.");
  cmd->add_option("log", opt->log, "LOG, LOG,POSES or LOG,slam, as for `map build`")->required();
  cmd->add_option("--out", opt->out, "path stem: writes OUT.yaml and OUT.pgm")->required();
  cmd->add_option("--resolution", opt->grid.resolution, "[m] cell edge")
      ->capture_default_str()
      ->check(within(0.001, 100));
  cmd->add_option("--max-range", opt->grid.max_range, "[m] returns beyond are not used")
      ->capture_default_str()
      ->check(within(0.01, 1000));
  cmd->add_flag("--slam", opt->slam, "pose a raw log given without a poses file by lshloc's SLAM");
  cmd->callback([opt] {
    // --out map.yaml means the stem map (not map.yaml.yaml); a folder is no stem.
    if (io::is_ros_map_path(opt->out)) opt->out = opt->out.substr(0, opt->out.rfind('.'));
    if (opt->out.empty() || opt->out.back() == '/' || std::filesystem::path(opt->out).filename().empty())
      throw Error("--out " + opt->out + ": expected a path stem such as maps/floor2 (writes floor2.yaml, floor2.pgm)");
    io::require_writable(opt->out + ".yaml");
    const Submap submap = load_map_argument(opt->log, opt->slam);
    const OccupancyGrid grid = build_occupancy_grid(submap.scans, opt->grid);
    io::write_ros_map(opt->out, grid);
    std::size_t occupied = 0, free = 0;
    for (const std::int8_t c : grid.cells) occupied += c == occupancy::kOccupied, free += c == occupancy::kFree;
    std::printf("%s.{yaml,pgm}: %zu x %zu cells of %.3f m, origin (%.2f, %.2f); %zu occupied, %zu free\n",
                opt->out.c_str(), grid.width, grid.height, grid.resolution, grid.origin.x(), grid.origin.y(), occupied,
                free);
  });
}

void add_compact(CLI::App& map_cmd) {
  auto path = std::make_shared<std::string>();
  auto* cmd = map_cmd.add_subcommand(
      "compact", "Fold a map's journal into a new snapshot (atomically: the file holds the old or the new form).");
  cmd->add_option("map", *path, "the map file")->required();
  cmd->callback([path] {
    const std::uint64_t before = file_bytes(*path);
    io::MapAppender appender(*path);
    print_warnings(appender.warnings());
    const io::MapFileInfo& current = appender.opened();
    nlohmann::json meta = current.meta;
    meta["compacted_journal_scans"] = current.journal_scans;
    const auto t0 = std::chrono::steady_clock::now();
    appender.compact(meta);
    std::printf("%s: compacted %zu journal scans in %.2f s; %llu -> %llu bytes\n", path->c_str(), current.journal_scans,
                seconds_since(t0), static_cast<unsigned long long>(before),
                static_cast<unsigned long long>(file_bytes(*path)));
  });
}

void add_from_redis(CLI::App& map_cmd) {
  struct Options {
    std::string url, out, prefix = "lshloc";
    double follow_s = 0.0;
  };
  auto opt = std::make_shared<Options>();
  auto* cmd = map_cmd.add_subcommand(
      "from-redis",
      "Save a fleet's map (docs/fleet.md) as a map file: every update its map log on Redis holds now, with\n"
      "each stream's position, so that `localize --map redis://... --map-snapshot FILE` (and `eval\n"
      "--map-redis ... --map-snapshot FILE`) start from it and read only what came after.");
  cmd->add_option("url", opt->url, "the Redis server, redis://HOST[:PORT]")->required();
  cmd->add_option("--out", opt->out, "the map file to write (atomically)")->required();
  cmd->add_option("--prefix", opt->prefix, "key prefix of the map on the server")->capture_default_str();
  cmd->add_option("--follow", opt->follow_s,
                  "[s] after the history, keep following the log (reconnecting if the server restarts) until no "
                  "update arrived for this long, then save")
      ->check(within(0, 1e6));
  cmd->callback([opt] {
    io::require_replaceable(opt->out);
    const auto t0 = std::chrono::steady_clock::now();
    fleet::MapFollower follower(fleet::RedisAddress::parse(opt->url),
                                fleet::MapFollowerConfig{.log = {.prefix = opt->prefix}});
    GlobalMap map(follower.settings());
    std::size_t updates = follower.catch_up(map);
    if (opt->follow_s > 0) {
      std::shared_mutex mutex;
      follower.start(map, mutex);
      std::size_t seen = 0;
      auto quiet_since = std::chrono::steady_clock::now();
      while (seconds_since(quiet_since) < opt->follow_s) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        const std::size_t now = follower.stats().live_updates;
        if (now != seen) seen = now, quiet_since = std::chrono::steady_clock::now();
      }
      follower.stop();
      updates += seen;
    }
    const double read_s = seconds_since(t0);
    io::save_map(opt->out, map,
                 {{"made_by", "lshloc map from-redis"},
                  {"map_log",
                   {{"redis", opt->url},
                    {"prefix", opt->prefix},
                    {"positions", fleet::positions_to_json(follower.applied_positions())}}}});
    const fleet::MapFollowerStats st = follower.stats();
    std::fprintf(stderr, "%s: %zu submaps, %zu scans, %zu features (read and applied in %.2f s, saved in %.2f s)\n",
                 opt->out.c_str(), map.submap_count(), map.stats().scans, map.stats().features, read_s,
                 seconds_since(t0) - read_s);
    warn_refused_scans(opt->url, st);
    const nlohmann::json j = {{"out", opt->out},
                              {"submaps", map.submap_count()},
                              {"scans", map.stats().scans},
                              {"features", map.stats().features},
                              {"updates", updates},
                              {"duplicates", st.duplicates},
                              {"reconnects", st.reconnects},
                              {"refused_scans", st.refused_scans},
                              {"read_s", read_s}};
    std::printf("%s\n", io::json_text(j).c_str());
  });
}

}  // namespace

void add_map_command(CLI::App& app, GlobalOptions& global) {
  (void)global;
  auto* cmd = app.add_subcommand("map", "Build, grow and check saved global maps (docs/map-format.md)");
  cmd->require_subcommand(1);
  add_build(*cmd);
  add_append(*cmd);
  add_info(*cmd);
  add_verify(*cmd);
  add_compact(*cmd);
  add_to_grid(*cmd);
  add_from_grid(*cmd);
  add_from_redis(*cmd);
}

}  // namespace lshloc::app
