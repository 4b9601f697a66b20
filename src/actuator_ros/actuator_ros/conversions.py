# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Message field conversions shared by the nodes."""

from __future__ import annotations

from builtin_interfaces.msg import Time


def ns_to_stamp(ns: int) -> Time:
    """Integer nanoseconds to builtin_interfaces/Time."""
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def joint_position(msg, joint_name: str) -> float | None:
    """Return the named joint's angle in a sensor_msgs/JointState, or None.

    A sole unnamed joint is accepted.
    """
    if msg.name:
        if joint_name not in msg.name:
            return None
        index = list(msg.name).index(joint_name)
    else:
        index = 0
    return msg.position[index] if index < len(msg.position) else None
