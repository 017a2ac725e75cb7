// lshloc_ros_node: global localization on a ROS 1 robot (docs/ros.md). The
// ROS side only: sensor_msgs/LaserScan and the odometry and laser mount from
// tf go in, /initialpose (what AMCL and nav2 take), ~pose, ~status, ~submap
// and optionally map -> odom come out. What it asks of lshloc is NodeCore
// (node_core.hpp); this file is C++17, as ROS 1's message headers need.
#include <algorithm>
#include <cmath>
#include <deque>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/LaserScan.h>
#include <std_msgs/String.h>
#include <std_srvs/Empty.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include "node_core.hpp"

namespace {

using lshloc::ros_node::PlainPose;

PlainPose pose_of(const geometry_msgs::Transform& t) {
  const auto& q = t.rotation;
  return {t.translation.x, t.translation.y,
          std::atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))};
}

void set_yaw(geometry_msgs::Quaternion& q, double theta) {
  q.x = 0.0, q.y = 0.0, q.z = std::sin(theta / 2.0), q.w = std::cos(theta / 2.0);
}

/// ~maps: a list of map sources, or one string of them separated by ';'.
std::vector<std::string> map_sources_param(ros::NodeHandle& pnh) {
  std::vector<std::string> sources;
  if (pnh.getParam("maps", sources)) return sources;
  std::string text;
  pnh.getParam("maps", text);
  for (std::size_t at = 0; at <= text.size();) {
    const std::size_t end = std::min(text.find(';', at), text.size());
    std::string one = text.substr(at, end - at);
    one.erase(0, one.find_first_not_of(" \t"));
    one.erase(one.find_last_not_of(" \t") + 1);
    if (!one.empty()) sources.push_back(one);
    at = end + 1;
  }
  return sources;
}

class LshlocNode {
 public:
  LshlocNode() : listener_(tf_) {
    pnh_.param<std::string>("global_frame", global_frame_, "map");
    pnh_.param<std::string>("odom_frame", odom_frame_, "odom");
    pnh_.param<std::string>("base_frame", base_frame_, "base_link");
    pnh_.param("publish_tf", publish_tf_, false);
    pnh_.param("transform_tolerance", transform_tolerance_s_, 0.1);
    pnh_.param<std::string>("odom_topic", odom_topic_, "");
    std::string config_file;
    pnh_.param<std::string>("config", config_file, "");
    initialpose_ = nh_.advertise<geometry_msgs::PoseWithCovarianceStamped>("initialpose", 2);
    pose_ = pnh_.advertise<geometry_msgs::PoseWithCovarianceStamped>("pose", 10);
    status_ = pnh_.advertise<std_msgs::String>("status", 10);
    submap_ = pnh_.advertise<std_msgs::String>("submap", 1, /*latch=*/true);
    std::vector<std::string> log;
    map_error_ = core_.load(map_sources_param(pnh_), config_file, log);
    for (const std::string& line : log) ROS_INFO("lshloc: %s", line.c_str());
    if (map_error_.empty())
      ROS_INFO("lshloc: map of %s", core_.map_summary().c_str());
    else  // the node keeps serving: each scan's status says why it cannot localize
      ROS_ERROR("lshloc: no map: %s", map_error_.c_str());
    if (!odom_topic_.empty()) odometry_ = nh_.subscribe(odom_topic_, 100, &LshlocNode::on_odometry, this);
    scans_ = nh_.subscribe("scan", 5, &LshlocNode::on_scan, this);
    global_localization_ = pnh_.advertiseService("global_localization", &LshlocNode::on_global_localization, this);
  }

 private:
  bool on_global_localization(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
    core_.restart();
    ROS_INFO("lshloc: global localization: starting over from nothing");
    return true;
  }

  /// The transform parent <- child at `stamp`, waiting a little for tf to catch up.
  bool lookup(const std::string& parent, const std::string& child, const ros::Time& stamp, PlainPose& out,
              bool warn = true) {
    // Waits up to 0.2 s of wall time for tf to catch up: a sim clock that stopped (a bag at its end) never
    // ends a wait counted in ROS time.
    std::string why;
    const ros::WallTime give_up = ros::WallTime::now() + ros::WallDuration(warn ? 0.2 : 0.0);
    bool known = tf_.canTransform(parent, child, stamp, &why);
    while (!known && ros::ok() && ros::WallTime::now() < give_up) {
      ros::WallDuration(0.005).sleep();
      known = tf_.canTransform(parent, child, stamp, &why);
    }
    if (!known) {
      if (warn)
        ROS_WARN_THROTTLE(5.0, "lshloc: no transform %s -> %s at %.3f s: %s; scan skipped", parent.c_str(),
                          child.c_str(), stamp.toSec(), why.c_str());
      return false;
    }
    try {
      out = pose_of(tf_.lookupTransform(parent, child, stamp).transform);
      return true;
    } catch (const tf2::TransformException& e) {
      ROS_WARN_THROTTLE(5.0, "lshloc: %s; scan skipped", e.what());
      return false;
    }
  }

  void on_odometry(const nav_msgs::Odometry::ConstPtr& msg) {
    const auto& p = msg->pose.pose;
    geometry_msgs::Transform t;
    t.translation.x = p.position.x, t.translation.y = p.position.y, t.rotation = p.orientation;
    // A stamp running back (a bag looped) empties the history, as tf does.
    if (!odometry_history_.empty() && msg->header.stamp < odometry_history_.back().first) odometry_history_.clear();
    odometry_history_.emplace_back(msg->header.stamp, pose_of(t));
    while (odometry_history_.size() > 200) odometry_history_.pop_front();
  }

  /// ~odom_topic's pose at `stamp`: interpolated between the messages around it (at most 0.5 s apart), or
  /// the nearest within 0.1 s.
  bool odometry_at(const ros::Time& stamp, PlainPose& out) {
    const auto after = std::find_if(odometry_history_.begin(), odometry_history_.end(),
                                    [&](const auto& m) { return m.first >= stamp; });
    if (after != odometry_history_.end() && after != odometry_history_.begin()) {
      const auto& [t1, b] = *after;
      const auto& [t0, a] = *std::prev(after);
      const double span = (t1 - t0).toSec(), f = span > 0.0 ? (stamp - t0).toSec() / span : 0.0;
      if (span <= 0.5) {
        out = {a.x + f * (b.x - a.x), a.y + f * (b.y - a.y),
               a.theta + f * std::remainder(b.theta - a.theta, 2.0 * M_PI)};
        return true;
      }
    }
    for (const auto& [t, pose] : odometry_history_)
      if (std::abs((t - stamp).toSec()) <= 0.1) return out = pose, true;
    ROS_WARN_THROTTLE(5.0, "lshloc: no %s message within 0.1 s of the scan at %.3f s; scan skipped",
                      odom_topic_.c_str(), stamp.toSec());
    return false;
  }

  /// The laser's pose on the robot at the scan's stamp; a frame resolved once keeps its mount when tf cannot
  /// say it again (a static transform lost when tf cleared its buffer on time running back).
  bool laser_mount(const sensor_msgs::LaserScan& msg, PlainPose& mount) {
    const auto known = mounts_.find(msg.header.frame_id);
    if (lookup(base_frame_, msg.header.frame_id, msg.header.stamp, mount, known == mounts_.end())) {
      mounts_[msg.header.frame_id] = mount;
      return true;
    }
    if (known == mounts_.end()) return false;
    mount = known->second;
    return true;
  }

  void on_scan(const sensor_msgs::LaserScan::ConstPtr& msg) {
    std_msgs::String status;
    const double stamp = msg->header.stamp.toSec();
    PlainPose odom, mount;
    if (!map_error_.empty()) {
      status.data = lshloc::ros_node::NodeCore::error_status(stamp, "no map: " + map_error_);
    } else if (!(odom_topic_.empty() ? lookup(odom_frame_, base_frame_, msg->header.stamp, odom)
                                     : odometry_at(msg->header.stamp, odom)) ||
               !laser_mount(*msg, mount)) {
      status.data = lshloc::ros_node::NodeCore::error_status(
          stamp, "no transform of the scan's frame '" + msg->header.frame_id + "' to " + odom_frame_);
    } else {
      try {
        lshloc::ros_node::PlainScan scan;
        scan.stamp = stamp;
        scan.angle_min = msg->angle_min, scan.angle_increment = msg->angle_increment;
        scan.range_min = msg->range_min, scan.range_max = msg->range_max;
        scan.ranges = msg->ranges;
        const lshloc::ros_node::NodeEstimate e = core_.add_scan(scan, odom, mount);
        for (const std::string& line : e.log) ROS_INFO("lshloc: %s", line.c_str());
        if (e.restarted)
          ROS_WARN("lshloc: time ran back to %.3f s (a bag looped, a robot restarted): localizing from nothing again",
                   stamp);
        publish(*msg, e, odom);
        status.data = e.status_json;
      } catch (const std::exception& ex) {
        ROS_ERROR_THROTTLE(5.0, "lshloc: scan at %.3f s: %s", stamp, ex.what());
        status.data = lshloc::ros_node::NodeCore::error_status(stamp, ex.what());
      }
    }
    status_.publish(status);
  }

  void publish(const sensor_msgs::LaserScan& msg, const lshloc::ros_node::NodeEstimate& e, const PlainPose& odom) {
    if (!e.has_estimate) return;
    geometry_msgs::PoseWithCovarianceStamped pose;
    pose.header.stamp = msg.header.stamp;
    pose.header.frame_id = global_frame_;
    pose.pose.pose.position.x = e.robot.x, pose.pose.pose.position.y = e.robot.y;
    set_yaw(pose.pose.pose.orientation, e.robot.theta);
    pose.pose.covariance[0] = pose.pose.covariance[7] = e.var_xy;
    pose.pose.covariance[35] = e.var_theta;
    pose_.publish(pose);
    if (e.announce) {
      initialpose_.publish(pose);
      ROS_INFO("lshloc: localized in %s: x %.2f m, y %.2f m, heading %.1f deg", e.submap.c_str(), e.robot.x, e.robot.y,
               e.robot.theta * 180.0 / M_PI);
    }
    if (e.submap_changed) {
      std_msgs::String submap;
      submap.data = e.submap;
      submap_.publish(submap);
    }
    if (publish_tf_ && e.confident) {
      // map -> odom, as AMCL gives it: the robot's map pose with its odometry taken off, a little ahead in time.
      const double c = std::cos(e.robot.theta - odom.theta), s = std::sin(e.robot.theta - odom.theta);
      geometry_msgs::TransformStamped t;
      t.header.stamp = msg.header.stamp + ros::Duration(transform_tolerance_s_);
      t.header.frame_id = global_frame_;
      t.child_frame_id = odom_frame_;
      t.transform.translation.x = e.robot.x - (c * odom.x - s * odom.y);
      t.transform.translation.y = e.robot.y - (s * odom.x + c * odom.y);
      set_yaw(t.transform.rotation, e.robot.theta - odom.theta);
      broadcaster_.sendTransform(t);
    }
  }

  ros::NodeHandle nh_, pnh_{"~"};
  tf2_ros::Buffer tf_;
  tf2_ros::TransformListener listener_;
  tf2_ros::TransformBroadcaster broadcaster_;
  ros::Publisher initialpose_, pose_, status_, submap_;
  ros::Subscriber scans_, odometry_;
  ros::ServiceServer global_localization_;
  std::string global_frame_, odom_frame_, base_frame_, odom_topic_, map_error_;
  std::deque<std::pair<ros::Time, PlainPose>> odometry_history_;  ///< ~odom_topic's newest messages
  bool publish_tf_ = false;
  double transform_tolerance_s_ = 0.1;
  std::map<std::string, PlainPose> mounts_;  ///< the laser mount of each scan frame resolved so far
  lshloc::ros_node::NodeCore core_;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "lshloc");
  LshlocNode node;
  ros::spin();
  return 0;
}
