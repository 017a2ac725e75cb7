#include "lshloc/runtime/session.hpp"

#include <cmath>
#include <mutex>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc {

void SessionConfig::validate() const {
  localizer.validate();
  require(restart_after_time_back_s > 0.0, "SessionConfig.restart_after_time_back_s", "> 0 (infinity: never)",
          restart_after_time_back_s);
  require(restart_after_gap_s > 0.0, "SessionConfig.restart_after_gap_s", "> 0 (infinity: never)", restart_after_gap_s);
}

LocalizerConfig with_target_laser_offset(LocalizerConfig config, const Pose2& target_offset) {
  // The laser offset comes from the target's log; a config may give one for
  // a log without it, but never another one than the log's.
  const Pose2& given = config.scan_matcher.laser_offset;
  const bool config_sets = given.x != 0.0 || given.y != 0.0 || given.theta != 0.0;
  const bool log_sets = target_offset.x != 0.0 || target_offset.y != 0.0 || target_offset.theta != 0.0;
  if (config_sets && log_sets &&
      (given.x != target_offset.x || given.y != target_offset.y || given.theta != target_offset.theta)) {
    throw Error("LocalizerConfig.scan_matcher.laser_offset: expected none or the target log's (" +
                std::to_string(target_offset.x) + ", " + std::to_string(target_offset.y) + ", " +
                std::to_string(target_offset.theta) + "), got (" + std::to_string(given.x) + ", " +
                std::to_string(given.y) + ", " + std::to_string(given.theta) + ")");
  }
  if (!config_sets) config.scan_matcher.laser_offset = target_offset;
  return config;
}

LocalizationSession::LocalizationSession(const GlobalMap& map, const SessionConfig& config, const Pose2& laser_offset,
                                         bool odometry, std::shared_mutex* map_mutex)
    : map_(map),
      config_(config),
      localizer_config_(with_target_laser_offset(config.localizer, laser_offset)),
      map_mutex_(map_mutex) {
  config_.validate();
  if (!odometry) localizer_config_.scan_matcher.odometry = false;
  std::shared_lock<std::shared_mutex> reading;
  if (map_mutex_) reading = std::shared_lock<std::shared_mutex>(*map_mutex_);
  localizer_ = std::make_unique<Localizer>(map_, localizer_config_);
}

LocalizationSession::~LocalizationSession() = default;

void LocalizationSession::restart() {
  std::shared_lock<std::shared_mutex> reading;
  if (map_mutex_) reading = std::shared_lock<std::shared_mutex>(*map_mutex_);
  start_over();
}

void LocalizationSession::start_over() {
  localizer_ = std::make_unique<Localizer>(map_, localizer_config_);
  any_scan_ = false;
  ++stats_.restarts;
}

LocalizationEstimate LocalizationSession::add_scan(const LaserScan& scan, const Look& look) {
  // The map's lock first: a new localizer reads the map too.
  std::shared_lock<std::shared_mutex> reading;
  if (map_mutex_) reading = std::shared_lock<std::shared_mutex>(*map_mutex_);
  last_restart_ = SessionRestart::kNone;
  if (any_scan_ && newest_stamp_ - scan.timestamp >= config_.restart_after_time_back_s) {
    start_over();
    ++stats_.time_back_restarts;
    last_restart_ = SessionRestart::kTimeWentBack;
  } else if (any_scan_ && scan.timestamp - newest_stamp_ >= config_.restart_after_gap_s) {
    start_over();
    ++stats_.gap_restarts;
    last_restart_ = SessionRestart::kGap;
  }
  newest_stamp_ = any_scan_ ? std::max(newest_stamp_, scan.timestamp) : scan.timestamp;
  any_scan_ = true;
  ++stats_.scans;
  LocalizationEstimate estimate = localizer_->add_scan(scan);
  if (look) look(*localizer_, estimate);
  return estimate;
}

}  // namespace lshloc
