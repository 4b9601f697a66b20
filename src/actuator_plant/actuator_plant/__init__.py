# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Simulated deep-sea oil-filled joint actuator: the ROS-free joint model and its plant node."""
