#pragma once
// A localization session: what a robot's driver (a ROS node, the `localize`
// stream, a batch replay) feeds with scans as they arrive and reads estimates
// from. It wraps one Localizer over a GlobalMap and adds what a live input
// needs: the target's laser mount, a start over on request (AMCL's
// global_localization), when time runs back (a bag looped, a robot
// restarted) and after a long gap, and an optional lock on a map that other
// threads write.
// Poses [m, rad], times [s].
// Thread safety: a session is not thread-safe (one caller at a time); with
// `map_mutex` it holds the map shared during each scan, so map writers on
// other threads must hold it exclusively; without, nothing may write the map
// while add_scan runs.
#include <functional>
#include <memory>
#include <shared_mutex>

#include "lshloc/localization/global_map.hpp"
#include "lshloc/localization/localizer.hpp"

namespace lshloc {

struct SessionConfig {
  LocalizerConfig localizer;
  /// [s] a scan stamped this far before the newest stamp so far starts the
  /// session over, as tf clears its buffer on a jump back in time; smaller
  /// steps back are the localizer's (raw logs step back by up to 0.9 s where
  /// stamps bunch). Infinity: never.
  double restart_after_time_back_s = 5.0;
  /// [s] a scan stamped this long after the one before starts the session
  /// over too: the laser was off that long (a robot restarted, a bag played
  /// on after another) and the robot may have been moved meanwhile, which
  /// odometry does not say. Infinity: never.
  double restart_after_gap_s = 60.0;

  /// The localizer's validate(), and positive restart_after_time_back_s and restart_after_gap_s.
  void validate() const;
};

struct SessionStats {
  std::size_t scans = 0;               ///< scans added since the session began (restarts included)
  std::size_t restarts = 0;            ///< starts over: asked for, on time running back, after a gap
  std::size_t time_back_restarts = 0;  ///< of which on a scan stamped restart_after_time_back_s back
  std::size_t gap_restarts = 0;        ///< of which after a gap of restart_after_gap_s
};

/// `config` with the target's laser offset: the target log's, or the
/// config's for a log without one; a config offset other than the log's
/// throws lshloc::Error.
LocalizerConfig with_target_laser_offset(LocalizerConfig config, const Pose2& target_offset);

/// Whether a LocalizationSession started over at a scan, and why.
enum class SessionRestart { kNone, kTimeWentBack, kGap };

class LocalizationSession {
 public:
  /// Called under the map lock right after a scan with the localizer and
  /// the scan's estimate; may be empty.
  using Look = std::function<void(const Localizer&, const LocalizationEstimate&)>;

  /// A session over `map` (which must outlive it) for a robot whose laser sits
  /// at `laser_offset` on it (robot -> laser). The config's scan matcher takes
  /// that offset unless it gives one for a robot without (Pose2() here); a
  /// config offset other than a non-zero `laser_offset` throws lshloc::Error.
  /// `odometry` false: the scans' odometry is not used (a laser alone).
  LocalizationSession(const GlobalMap& map, const SessionConfig& config, const Pose2& laser_offset,
                      bool odometry = true, std::shared_mutex* map_mutex = nullptr);
  ~LocalizationSession();
  LocalizationSession(const LocalizationSession&) = delete;
  LocalizationSession& operator=(const LocalizationSession&) = delete;

  /// Localizes one scan (its `odometry` the robot's odometry pose at the
  /// scan's time, its `timestamp` the scan's) and returns its estimate.
  LocalizationEstimate add_scan(const LaserScan& scan, const Look& look = {});
  /// Starts over from nothing (AMCL's global_localization): the next scan is
  /// the first of a new localizer over the same map.
  void restart();

  /// Whether the last add_scan started over first, and why.
  SessionRestart last_restart() const { return last_restart_; }
  /// The localizer of the session so far (since the last start over).
  const Localizer& localizer() const { return *localizer_; }
  /// The localizer's settings as the session applies them (the laser offset in).
  const LocalizerConfig& localizer_config() const { return localizer_config_; }
  /// The robot's pose from the laser pose an estimate gives: pose * robot_from_laser().
  Pose2 robot_from_laser() const { return localizer_config_.scan_matcher.laser_offset.inverse(); }
  const SessionStats& stats() const { return stats_; }

 private:
  void start_over();  ///< restart() with the map's lock held

  const GlobalMap& map_;
  SessionConfig config_;
  LocalizerConfig localizer_config_;
  std::shared_mutex* map_mutex_;
  std::unique_ptr<Localizer> localizer_;
  double newest_stamp_ = 0.0;
  bool any_scan_ = false;
  SessionRestart last_restart_ = SessionRestart::kNone;
  SessionStats stats_;
};

}  // namespace lshloc
