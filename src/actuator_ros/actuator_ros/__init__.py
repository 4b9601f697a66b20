# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""rclpy helpers shared by the nodes (the only package of helpers that imports rclpy)."""
