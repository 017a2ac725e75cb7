// `lshloc mapper`: a mapper robot of a fleet (docs/fleet.md). Publishes one
// mapped log's scans, with their poses, as one submap's stream of the map log
// on Redis; localizers anywhere follow it (`lshloc localize --map redis://...`).
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "localizer_options.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/common/wall_time.hpp"
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
  double rate_hz = 0.0;
  bool log_speed = false;
  bool slam = false;
  std::size_t batch = 256;
  LocalizerOptions settings;
};

void run_mapper(const MapperOptions& opt) {
  const Submap source = load_map_argument(opt.log, opt.slam);
  if (source.scans.empty()) throw Error(opt.log + ": no laser scans to publish");
  const std::string name = opt.submap.empty() ? source.name : opt.submap;
  fleet::RedisConnection redis(fleet::RedisAddress::parse(opt.redis));
  fleet::MapLogWriter writer(redis, name, make_run_config(opt.settings).map,
                             fleet::MapLogConfig{.prefix = opt.prefix, .batch = opt.batch});
  const std::uint64_t first_seq = writer.next_seq();
  const bool tty = isatty(fileno(stderr));
  const auto t0 = std::chrono::steady_clock::now();
  const std::span<const LaserScan> scans(source.scans);
  const bool paced = opt.rate_hz > 0.0 || opt.log_speed;
  for (std::size_t i = 0; i < scans.size();) {
    // Paced: one scan at a time when it is due; else batches as fast as Redis takes them.
    std::size_t n = paced ? 1 : std::min(opt.batch, scans.size() - i);
    if (paced) {
      const double due =
          opt.log_speed ? scans[i].timestamp - scans.front().timestamp : static_cast<double>(i) / opt.rate_hz;
      const double wait = due - seconds_since(t0);
      if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait));
    }
    writer.publish(scans.subspan(i, n));
    i += n;
    if (tty && (i % 500 < n || i == scans.size()))
      std::fprintf(stderr, "\r%s: %zu/%zu scans published%s", name.c_str(), i, scans.size(),
                   i == scans.size() ? "\n" : "");
  }
  const double wall = seconds_since(t0);
  nlohmann::json j = {{"redis", redis.address().url()},
                      {"submap", name},
                      {"scans", scans.size()},
                      {"first_seq", first_seq},
                      {"next_seq", writer.next_seq()},
                      {"seconds", wall},
                      {"scans_per_s", wall > 0 ? static_cast<double>(scans.size()) / wall : 0.0}};
  std::printf("%s\n", j.dump().c_str());
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
  cmd->add_option("--redis", opt->redis, "the Redis server, redis://HOST[:PORT]")->capture_default_str();
  cmd->add_option("--submap", opt->submap, "the submap's name (default: the log's file name)");
  cmd->add_option("LOG", opt->log, "the mapped log: LOG, LOG,POSES or LOG,slam")->required();
  cmd->add_option("--rate", opt->rate_hz, "scans per second (0: as fast as Redis takes them)")
      ->capture_default_str()
      ->check(within(0, 1e6));
  cmd->add_flag("--log-speed", opt->log_speed, "publish at the log's own pace (its time stamps)");
  cmd->add_option("--prefix", opt->prefix, "key prefix of the map on the server")->capture_default_str();
  cmd->add_option("--batch", opt->batch, "scans per pipelined round trip when not paced")
      ->capture_default_str()
      ->check(within(1, 100000));
  cmd->add_flag("--slam", opt->slam, "a log given without poses is raw: pose it by lshloc's SLAM");
  add_localizer_options(*cmd, opt->settings);
  cmd->callback([opt, &global] {
    (void)global;
    if (print_config_if_asked(opt->settings)) return;
    if (opt->rate_hz > 0 && opt->log_speed) throw Error("mapper: give --rate or --log-speed, not both");
    run_mapper(*opt);
  });
}

}  // namespace lshloc::app
