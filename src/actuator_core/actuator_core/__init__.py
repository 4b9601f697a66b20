# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""ROS-free core.

Limits and nominal constants, parameter specifications, elementwise math, sample timing, sample
protocol, status codes and run metrics (no rclpy, no launch).
"""
