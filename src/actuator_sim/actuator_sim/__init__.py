# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""ROS-free closed loop, scenarios, offline simulation.

Stability analysis and the late-command study.
"""
