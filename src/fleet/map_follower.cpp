#include "lshloc/fleet/map_follower.hpp"

#include <chrono>
#include <thread>

#include "lshloc/common/error.hpp"

namespace lshloc::fleet {

MapFollower::MapFollower(RedisAddress address, MapFollowerConfig config)
    : config_(std::move(config)),
      redis_(std::move(address), config_.timeout_s),
      reader_(redis_, config_.log),
      settings_(reader_.settings()) {}

MapFollower::~MapFollower() { stop(); }

std::size_t MapFollower::catch_up(GlobalMap& map) {
  std::size_t n = 0;
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    try {
      const std::vector<MapUpdate> updates = reader_.poll();
      if (updates.empty()) break;
      const AppliedUpdates applied = apply_updates(map, reader_.submaps(), updates);
      n += applied.added;
      note_failures(applied);
    } catch (const MapLogRecordError&) {
      throw;  // the log itself is damaged: said at once, not after give_up_s of reconnecting
    } catch (const Error& e) {
      // A server restart: positions are kept; reconnect and read on, for a while.
      if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > config_.give_up_s) throw;
      {
        std::lock_guard lock(stats_mutex_);
        stats_.last_error = e.what();
      }
      std::this_thread::sleep_for(std::chrono::duration<double>(config_.retry_s));
      try {
        reader_.reconnect();
        std::lock_guard lock(stats_mutex_);
        ++stats_.reconnects;
      } catch (const Error&) {
      }
    }
  }
  apply_updates(map, reader_.submaps(), {});  // submaps registered without scans yet
  std::lock_guard lock(stats_mutex_);
  stats_.history_updates += n;
  stats_.duplicates = reader_.stats().duplicates;
  applied_ = reader_.positions();
  return n;
}

std::vector<StreamPosition> MapFollower::applied_positions() const {
  std::lock_guard lock(stats_mutex_);
  return applied_;
}

void MapFollower::start(GlobalMap& map, std::shared_mutex& mutex) {
  stop();
  stop_ = false;
  thread_ = std::thread([this, &map, &mutex] { follow(map, mutex); });
}

void MapFollower::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void MapFollower::note_failures(const AppliedUpdates& applied) {
  const std::string stopped = reader_.stats().stopped;  // a poll that stopped early is a failure too
  if (applied.refused == 0 && stopped.empty()) return;
  std::lock_guard lock(stats_mutex_);
  stats_.refused_scans += applied.refused;
  if (applied.refused) stats_.last_refusal = applied.last_refusal;
  if (!stopped.empty()) stats_.last_error = stopped;
}

MapFollowerStats MapFollower::stats() const {
  std::lock_guard lock(stats_mutex_);
  return stats_;
}

void MapFollower::follow(GlobalMap& map, std::shared_mutex& mutex) {
  bool connected = true;
  while (!stop_) {
    try {
      if (!connected) {
        reader_.reconnect();
        connected = true;
        std::lock_guard lock(stats_mutex_);
        ++stats_.reconnects;
        stats_.connected = true;
      }
      const std::vector<MapUpdate> updates = reader_.poll(config_.block_s);
      if (updates.empty()) continue;
      std::unique_lock map_lock(mutex);
      const AppliedUpdates applied = apply_updates(map, reader_.submaps(), updates);
      note_failures(applied);
      std::lock_guard lock(stats_mutex_);
      stats_.live_updates += applied.added;
      stats_.duplicates = reader_.stats().duplicates;
      applied_ = reader_.positions();
    } catch (const MapLogRecordError& e) {
      // Reconnecting would meet the same entry again: following stops, and stats() names the entry.
      std::lock_guard lock(stats_mutex_);
      stats_.last_error = std::string("following stopped: ") + e.what();
      stats_.stopped = true;
      return;
    } catch (const Error& e) {
      {
        std::lock_guard lock(stats_mutex_);
        stats_.last_error = e.what();
        stats_.connected = false;
      }
      connected = false;
      std::this_thread::sleep_for(std::chrono::duration<double>(config_.retry_s));
    } catch (const std::exception& e) {
      // Not a failure of the link or the log (memory, a library's limits): following stops, the process
      // and the map it has so far live on, and stats() says why.
      std::lock_guard lock(stats_mutex_);
      stats_.last_error = std::string("following stopped: ") + e.what();
      stats_.stopped = true;
      return;
    }
  }
}

}  // namespace lshloc::fleet
