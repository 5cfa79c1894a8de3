#!/usr/bin/env python3
"""A stand-in for the third-party Kinect driver that vi_robot.launch.py starts with start_kinect:=true
(tests/test_real_launch.py installs it as package `stand_in_kinect`): a node that offers its
organized cloud on a topic named `points`, which the launch file must remap onto
camera/depth/points. It publishes nothing: the test only looks for the publisher in the graph."""

from __future__ import annotations

import sys

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2

from tiling_ros.spinning import run_node


def kinect() -> Node:
    """The stand-in driver's node, offering its (never published) cloud."""
    node = rclpy.create_node("kinect")
    node.create_publisher(PointCloud2, "points", 1)
    return node


if __name__ == "__main__":
    sys.exit(run_node(kinect))
