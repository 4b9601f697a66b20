# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Extended state observer of the joint actuator: the ROS-free observer and its node."""
