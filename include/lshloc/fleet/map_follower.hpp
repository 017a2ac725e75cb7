#pragma once
// Keeps a localizer's in-memory global map up to date with the fleet's map
// log (docs/fleet.md): catch_up() applies the history, then a thread of its
// own follows every submap's stream and applies what arrives, holding the
// map's lock exclusively for each batch (the live map's concurrent path:
// localizers hold it shared for each target scan, eval/scenario_runner.hpp).
// Times [s].
// Thread safety: construct, catch_up(), start() and stop() from one thread;
// stats() from any thread.
#include <atomic>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <string>
#include <thread>

#include "lshloc/fleet/map_log.hpp"

namespace lshloc::fleet {

struct MapFollowerConfig {
  MapLogConfig log;
  double block_s = 0.2;     ///< [s] how long one read waits for new updates (also how soon stop() returns)
  double retry_s = 0.5;     ///< [s] between reconnect attempts after the server went away
  double give_up_s = 60.0;  ///< [s] catch_up() stops retrying after this long
  double timeout_s = 5.0;   ///< [s] of one command beyond its wait
};

struct MapFollowerStats {
  std::size_t history_updates = 0;  ///< applied by catch_up()
  std::size_t live_updates = 0;     ///< applied by the following thread
  std::size_t duplicates = 0;
  std::size_t reconnects = 0;
  std::string last_error;         ///< the last failure the thread recovered from (empty: none)
  std::size_t refused_scans = 0;  ///< updates the map refused (apply_updates()), skipped
  std::string last_refusal;       ///< why the last one was refused (empty: none)
  bool stopped = false;           ///< the thread stopped on a failure it cannot recover from (last_error says which)
  bool connected = true;          ///< false while the server is lost (the thread retries every retry_s)
};

class MapFollower {
 public:
  /// Connects and reads the map's settings (MapLogReader::settings()).
  MapFollower(RedisAddress address, MapFollowerConfig config = {});
  ~MapFollower();

  /// The map's settings: build the GlobalMap with them.
  const GlobalMapConfig& settings() const { return settings_; }

  /// Continues from a snapshot of the map (a map file `lshloc map from-redis`
  /// wrote, with its stream positions): call before catch_up(), which then
  /// applies only what came after the snapshot.
  void resume(const std::vector<StreamPosition>& positions) { reader_.resume(positions); }

  /// Applies every update already in the log to `map` (no lock: before any
  /// localizer reads it), reconnecting for up to give_up_s if the server goes
  /// away. Returns the updates applied. A damaged entry or a gap throws
  /// MapLogRecordError at once (after what came before it is applied).
  std::size_t catch_up(GlobalMap& map);
  /// The stream positions of what has been applied to the map so far (read
  /// it while holding the map's lock, shared, for a consistent snapshot).
  std::vector<StreamPosition> applied_positions() const;
  /// Follows the log on a thread of its own until stop(): each batch is
  /// applied under `mutex` held exclusively. A lost server is retried every
  /// retry_s; positions are kept, so nothing is applied twice or skipped. A
  /// damaged entry or a gap stops the following (stats(): stopped, last_error).
  void start(GlobalMap& map, std::shared_mutex& mutex);
  /// Stops the thread (within about block_s) and applies nothing more.
  void stop();

  MapFollowerStats stats() const;

 private:
  void follow(GlobalMap& map, std::shared_mutex& mutex);
  void note_failures(const AppliedUpdates& applied);
  MapFollowerConfig config_;
  RedisClient redis_;
  MapLogReader reader_;
  GlobalMapConfig settings_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  mutable std::mutex stats_mutex_;
  MapFollowerStats stats_;
  std::vector<StreamPosition> applied_;  ///< guarded by stats_mutex_
};

}  // namespace lshloc::fleet
