// `lshloc mapper`: a mapper robot of a fleet (docs/fleet.md). Publishes one
// mapped log's scans, with their poses, as one submap's stream of the map log
// on Redis; localizers anywhere follow it (`lshloc localize --map redis://...`).
// `lshloc mapper-scenario` (research) publishes (a share of) an evaluation
// scenario's submaps instead, for `lshloc eval --map-redis`.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "lshloc/io/config_json.hpp"
#include "lshloc/io/scan_record.hpp"
#include "localizer_options.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"
#include "lshloc/eval/dataset_catalog.hpp"
#include "lshloc/fleet/map_log.hpp"
#include "map_source.hpp"
#include "option_checks.hpp"

namespace lshloc::app {

namespace {

struct MapperOptions {
  std::string redis = "redis://127.0.0.1:6379";
  std::string submap;
  std::string log;
  std::string prefix = "lshloc";
  std::string rate = "0";  ///< scans per second, or "log": the log's own pace
  double rate_hz = 0.0;
  bool log_speed = false;
  std::size_t batch = 256;
  ScenarioConfig scenario{.building = ""};  ///< with --building: the scenario whose submaps to publish
  std::string part = "0/1";                 ///< K/N: submaps k with k % N == K
  std::size_t together = 0;                 ///< wait until this many mappers are ready, then publish at once
  double retry_s = 60.0;                    ///< [s] how long to keep reconnecting after the server went away
  std::string slam_cache;  ///< --slam-cache: a directory of SLAM poses of buildings without a corrected log
  LocalizerOptions settings;
};

/// The submaps this mapper publishes: the log's, or its part of the scenario's
/// (`registered`: every submap of the scenario, in its order).
std::vector<Submap> submaps_to_publish(const MapperOptions& opt, const std::string& data_dir,
                                       std::vector<std::string>& registered) {
  if (opt.scenario.building.empty()) {
    Submap s = load_map_argument(opt.log, false);
    if (s.scans.empty()) throw Error(opt.log + ": no laser scans to publish");
    if (!opt.submap.empty()) s.name = opt.submap;
    registered = {s.name};
    return {std::move(s)};
  }
  std::size_t k = 0, n = 0;
  char slash = 0;
  std::istringstream in(opt.part);
  if (!(in >> k >> slash >> n) || slash != '/' || n == 0 || k >= n || !in.eof())
    throw Error("--part '" + opt.part + "': expected K/N with 0 <= K < N");
  const io::DatasetCatalog catalog(data_dir);
  Scenario sc = io::load_scenario(catalog, opt.scenario, {}, slam_pose_cache(opt.slam_cache));
  std::vector<Submap> mine;
  for (const Submap& s : sc.submaps) registered.push_back(s.name);
  for (std::size_t i = k; i < sc.submaps.size(); i += n) mine.push_back(std::move(sc.submaps[i]));
  return mine;
}

/// [s] since the Unix epoch: mappers in several processes compare their times.
double unix_seconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

/// Reconnects (every 0.5 s, for at most `timeout_s`) and resyncs every
/// writer; throws when it gives up.
void reconnect_within(fleet::RedisClient& redis, std::vector<fleet::MapLogWriter>& writers, double timeout_s,
                      const std::string& why) {
  std::fprintf(stderr, "lshloc mapper: %s; reconnecting\n", why.c_str());
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    try {
      redis.reconnect();
      for (auto& w : writers) w.resync();
      return;
    } catch (const Error& e) {
      if (seconds_since(start) > timeout_s) throw Error(std::string(e.what()) + " (gave up reconnecting)");
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
  }
}

/// Waits until `n` mappers reached the barrier key (so that they publish at
/// once: the ingest figure), at most `timeout_s`.
void wait_for_mappers(fleet::RedisClient& redis, const std::string& key, std::size_t n, double timeout_s) {
  redis.command({"INCR", key});
  const auto start = std::chrono::steady_clock::now();
  while (true) {
    const fleet::Reply r = redis.command({"GET", key});
    if (!r.is_nil() && std::stoll(r.text) >= static_cast<long long>(n)) return;
    if (seconds_since(start) > timeout_s)
      throw Error(redis.address().url() + " " + key + ": fewer than " + std::to_string(n) + " mappers arrived in " +
                  std::to_string(timeout_s) + " s");
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

void run_mapper(const MapperOptions& opt, const std::string& data_dir) {
  std::vector<std::string> registered;
  const std::vector<Submap> sources = submaps_to_publish(opt, data_dir, registered);
  fleet::RedisClient redis(fleet::RedisAddress::parse(opt.redis));
  const GlobalMapConfig settings = make_run_config(opt.settings).map;
  // The scenario's submaps in its order, whichever of its mappers comes first:
  // every run of the scenario gives localizers the same submap ids.
  const fleet::MapLogConfig log_config{.prefix = opt.prefix, .batch = opt.batch};
  fleet::register_map(redis, settings, registered, log_config);
  std::vector<fleet::MapLogWriter> writers;
  std::size_t total = 0;
  for (const Submap& s : sources) {
    writers.emplace_back(redis, s.name, settings, log_config);
    total += s.scans.size();
  }
  // A scan no follower could read stops here, before anything is sent (publish() refuses it too).
  for (const Submap& s : sources)
    for (const LaserScan& scan : s.scans)
      if (const char* problem = io::scan_update_problem(scan, scan.pose))
        throw Error(s.name + ": the scan at t=" + std::to_string(scan.timestamp) + " cannot be published: expected " +
                    problem);
  std::vector<std::uint64_t> first_seq;
  for (const auto& w : writers) first_seq.push_back(w.next_seq());
  if (opt.together > 0) wait_for_mappers(redis, opt.prefix + ":barrier", opt.together, 3600.0);
  const bool tty = isatty(fileno(stderr));
  const auto t0 = std::chrono::steady_clock::now();
  const bool paced = opt.rate_hz > 0.0 || opt.log_speed;
  // Round robin over the submaps, as robots mapping at once: one scan each
  // when paced, else a batch each, as fast as Redis takes them.
  std::vector<std::size_t> done(sources.size(), 0);
  std::size_t published = 0, reconnects = 0;
  const double started_at = unix_seconds();
  // A server that answers but takes no writes (out of memory, read-only):
  // reconnecting succeeds every time, so progress, not the connection, bounds the retries.
  auto failing_since = std::chrono::steady_clock::now();  // with `failing`: the first failure since progress
  bool failing = false;
  while (published < total) {
    for (std::size_t r = 0; r < sources.size(); ++r) {
      const std::span<const LaserScan> scans(sources[r].scans);
      if (done[r] >= scans.size()) continue;
      const std::size_t n = paced ? 1 : std::min(opt.batch, scans.size() - done[r]);
      if (paced) {
        // At log speed each submap keeps its own log's pace (logs of other buildings have other clocks).
        const double due = opt.log_speed ? scans[done[r]].timestamp - scans.front().timestamp
                                         : static_cast<double>(published) / opt.rate_hz;
        const double wait = due - seconds_since(t0);
        if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait));
      }
      try {
        writers[r].publish(scans.subspan(done[r], n));
        done[r] += n, published += n;
        failing = false;
      } catch (const Error& e) {
        if (!failing) {
          failing = true, failing_since = std::chrono::steady_clock::now();
        } else {
          if (seconds_since(failing_since) > opt.retry_s)
            throw Error(std::string(e.what()) + " (no scan published for " + std::to_string(opt.retry_s) +
                        " s: gave up)");
          std::this_thread::sleep_for(std::chrono::milliseconds(500));
        }
        // The server went away (a restart): reconnect, and go on from what each stream holds.
        reconnect_within(redis, writers, opt.retry_s, e.what());
        ++reconnects;
        published = 0;
        for (std::size_t q = 0; q < writers.size(); ++q) {
          if (writers[q].next_seq() < first_seq[q])
            throw Error(log_config.stream_key(sources[q].name) + " at " + redis.address().url() +
                        ": the server holds updates up to sequence number " + std::to_string(writers[q].next_seq()) +
                        " but this mapper started at " + std::to_string(first_seq[q]) +
                        ": it lost updates it had acknowledged");
          done[q] = std::min(sources[q].scans.size(), static_cast<std::size_t>(writers[q].next_seq() - first_seq[q]));
          published += done[q];
        }
      }
      if (tty && (published % 500 < n || published == total))
        std::fprintf(stderr, "\rpublished %zu/%zu scans of %zu submaps%s", published, total, sources.size(),
                     published == total ? "\n" : "");
    }
  }
  const double wall = seconds_since(t0);
  nlohmann::json subs = nlohmann::json::array();
  for (std::size_t r = 0; r < sources.size(); ++r)
    subs.push_back({{"submap", sources[r].name},
                    {"scans", sources[r].scans.size()},
                    {"first_seq", first_seq[r]},
                    {"next_seq", writers[r].next_seq()}});
  nlohmann::json j = {{"redis", redis.address().url()},
                      {"scans", total},
                      {"seconds", wall},
                      {"scans_per_s", wall > 0 ? static_cast<double>(total) / wall : 0.0},
                      {"started_at", started_at},
                      {"finished_at", unix_seconds()},
                      {"reconnects", reconnects},
                      {"submaps", subs}};
  if (sources.size() == 1) j.update(subs[0]);  // one log: its fields at the top level too
  std::printf("%s\n", io::json_text(j).c_str());
}

}  // namespace

namespace {

/// --rate HZ or --rate log into the options.
void parse_rate(MapperOptions& opt) {
  opt.log_speed = opt.rate == "log";
  if (opt.log_speed) return;
  std::size_t used = 0;
  try {
    opt.rate_hz = std::stod(opt.rate, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != opt.rate.size() || !(opt.rate_hz >= 0.0 && opt.rate_hz <= 1e6))
    throw Error("--rate " + opt.rate +
                ": expected scans per second in [0, 1e6] (0: as fast as Redis takes them) or "
                "log (the log's own pace)");
}

/// The options both mapper commands take: the server, the pace, the fleet's settings.
void add_publishing_options(CLI::App& cmd, MapperOptions& opt) {
  cmd.add_option("--redis", opt.redis, "the Redis server and the map's key prefix, redis://HOST[:PORT][?prefix=P]")
      ->capture_default_str();
  cmd.add_option("--rate", opt.rate,
                 "scans per second (0: as fast as Redis takes them), or log: the log's own pace (its time stamps)")
      ->capture_default_str();
  cmd.add_option("--together", opt.together,
                 "wait until this many mappers (counted on the server) are ready, then publish at once")
      ->check(within(0, 10000));
  cmd.add_option("--retry", opt.retry_s, "[s] keep reconnecting this long after the server went away")
      ->capture_default_str()
      ->check(within(0, 1e6));
  cmd.add_option("--batch", opt.batch, "scans per pipelined round trip when not paced")
      ->capture_default_str()
      ->check(within(1, 100000));
  add_localizer_options(cmd, opt.settings);
}

/// The server and prefix from --redis (?prefix=P), the prefix option where one was given.
void resolve_redis(MapperOptions& opt, bool prefix_given) {
  const io::MapSource source = io::MapSource::parse(opt.redis);
  if (source.kind != io::MapSourceKind::kFleet || !source.snapshot.empty())
    throw Error("--redis " + opt.redis + ": expected redis://HOST[:PORT][?prefix=P]");
  opt.redis = source.path;
  if (!prefix_given) opt.prefix = source.prefix;
}

}  // namespace

void add_mapper_command(CLI::App& app, GlobalOptions& global) {
  auto opt = std::make_shared<MapperOptions>();
  auto* cmd = app.add_subcommand(
      "mapper",
      "A mapper robot of a fleet: publishes a mapped log's scans with their poses to the map log on Redis,\n"
      "as one submap's stream (docs/fleet.md). LOG takes the log's own FLASER poses, LOG,POSES a\n"
      "`timestamp x y theta` file or TUM trajectory, LOG,slam lshloc's SLAM over a raw log. A restarted\n"
      "mapper continues its submap's sequence. Prints one JSON line: scans, sequence numbers, scans/s.");
  auto* log = cmd->add_option("LOG", opt->log, "the mapped log: LOG, LOG,POSES or LOG,slam");
  cmd->add_option("--submap", opt->submap, "the submap's name (default: the log's file name)");
  add_publishing_options(*cmd, *opt);
  // The former --prefix, kept working for scripts: --redis redis://HOST:PORT?prefix=P says it now.
  auto* prefix = cmd->add_option("--prefix", opt->prefix)->group("");
  cmd->callback([opt, log, prefix, &global] {
    if (print_config_if_asked(opt->settings)) return;
    require_given({log});
    if (prefix->count() > 0)
      print_warnings({"--prefix " + opt->prefix + ": say it in the server's URL, --redis " + opt->redis +
                      "?prefix=" + opt->prefix + " (--prefix will go)"});
    resolve_redis(*opt, prefix->count() > 0);
    parse_rate(*opt);
    run_mapper(*opt, global.resolved_data_dir());
  });
}

void add_mapper_scenario_command(CLI::App& app, GlobalOptions& global) {
  auto opt = std::make_shared<MapperOptions>();
  auto* cmd = app.add_subcommand(
      "mapper-scenario",
      "Mapper robots of a fleet publishing an evaluation scenario's submaps (its target's building\n"
      "without the window and guard, and R-1 others; or a part of them) to the map log on Redis, for\n"
      "`lshloc eval --map-redis`. Prints one JSON line as `lshloc mapper` does.");
  auto* building = cmd->add_option("--building", opt->scenario.building, "the scenario's target building (required)");
  cmd->add_option("--submaps", opt->scenario.submaps, "R, the scenario's submaps")
      ->capture_default_str()
      ->check(within(1, 15));
  auto* start =
      cmd->add_option("--start", opt->scenario.start, "the target window's first scan (default: the building's)");
  cmd->add_option("--part", opt->part, "publish submaps k with k % N == K (K/N), one of N mappers")
      ->capture_default_str();
  auto* prefix =
      cmd->add_option("--prefix", opt->prefix, "key prefix of the map on the server (or --redis ...?prefix=P)");
  add_slam_cache_option(*cmd, opt->slam_cache);
  add_publishing_options(*cmd, *opt);
  cmd->callback([opt, building, start, prefix, &global] {
    if (print_config_if_asked(opt->settings)) return;
    require_given({building});
    if (start->count() == 0) opt->scenario.start = default_window_start(opt->scenario.building);
    resolve_redis(*opt, prefix->count() > 0);
    parse_rate(*opt);
    run_mapper(*opt, global.resolved_data_dir());
  });
}

}  // namespace lshloc::app
