# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Recording, playback, repair and analysis of rosbag2 (MCAP) bags of the actuator node suite.

ROS-free modules: ``bag_format`` (BagWriter: rosbag2 v9 folder + MCAP file), ``bag_qos``
(offered-QoS records), ``datafile`` (the data file: cut back after a failed write, full-disk
test hook), ``msgdefs`` (full .msg definitions and RIHS01 hashes), ``reading`` (opening bags
with rosbags), ``scan`` (damage-tolerant MCAP scan), ``repair`` (``bag_repair``), ``analyze``
(``bag_analyze``), ``outputs`` (where tools may write), ``progress``, ``errors``, ``recording``
(the recorder's topics, options and writer thread).
Nodes (rclpy): ``recorder_node`` (``recorder``), ``player_node`` (``player``), with
``ros_common`` shared between them; ``entry`` starts both with signals quiet during imports.
"""
