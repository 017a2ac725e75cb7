#!/usr/bin/env python3
"""A sketch of a ROS 2 node around lshloc: subscribes to /scan and /odom,
localizes globally in a saved lshloc map, and publishes the pose once
confident. UNTESTED HERE: ROS 2 is not packaged for this system (Debian 12),
so this file is a starting point, not a tested component.

    ros2 run <your_package> lshloc_node --ros-args -p map:=/path/to/building.map
"""
import math

import rclpy
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from sensor_msgs.msg import LaserScan

import lshloc


class LshlocNode(Node):
    def __init__(self):
        super().__init__("lshloc")
        self.declare_parameter("map", "")
        # base_link -> laser (x, y, yaw): the robot pose is published, the laser's taken off by it.
        self.declare_parameter("laser_offset", [0.0, 0.0, 0.0])
        self.gmap = lshloc.load_map(self.get_parameter("map").value)
        self.localizer = lshloc.Localizer(self.gmap, laser_offset=tuple(self.get_parameter("laser_offset").value))
        self.odom = (0.0, 0.0, 0.0)
        self.create_subscription(Odometry, "odom", self.on_odom, 50)
        self.create_subscription(LaserScan, "scan", self.on_scan, 10)
        self.pub = self.create_publisher(PoseWithCovarianceStamped, "lshloc/pose", 10)

    def on_odom(self, msg):
        self.odom = lshloc.pose_from_ros(msg)  # (x, y, yaw) of nav_msgs/Odometry

    def on_scan(self, msg):
        # The message's beams as lshloc reads them (+inf: no return; below range_min: invalid), its stamp in s.
        scan = lshloc.LaserScan.from_ros(msg, odometry=self.odom)
        e = self.localizer.add_scan(scan)
        # "confident": the flag, unless another scan stamped within 5 ms was estimated elsewhere.
        if not e["confident"]:
            return
        out = PoseWithCovarianceStamped()
        out.header.stamp = msg.header.stamp
        out.header.frame_id = e["submap_name"]  # one frame per submap (building)
        x, y, theta = e["robot_pose"]
        out.pose.pose.position.x, out.pose.pose.position.y = x, y
        out.pose.pose.orientation.z, out.pose.pose.orientation.w = math.sin(theta / 2), math.cos(theta / 2)
        # A diagonal covariance a planner can read; lshloc gives no per-pose covariance, so these are the
        # errors measured on confident scans (RESULTS.md: centimetres, under a degree), made generous.
        out.pose.covariance[0] = out.pose.covariance[7] = 0.1 ** 2
        out.pose.covariance[35] = math.radians(3.0) ** 2
        self.pub.publish(out)


def main():
    rclpy.init()
    rclpy.spin(LshlocNode())


if __name__ == "__main__":
    main()
