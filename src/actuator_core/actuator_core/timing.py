# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Sample-time arithmetic shared by the nodes and the offline loop.

So both compute identical times.
"""

from __future__ import annotations


def period_ns(dt_s: float) -> int:
    """Sample period in integer nanoseconds (the unit of ROS stamps)."""
    return int(round(dt_s * 1.0e9))


def sample_time_s(elapsed_ns: int) -> float:
    """Seconds since the start of the run from integer nanoseconds.

    One rounding, same everywhere.
    """
    return elapsed_ns * 1.0e-9


def stamp_to_ns(stamp) -> int:
    """Return a builtin_interfaces/Time as integer nanoseconds.

    Any object with sec and nanosec is accepted.
    """
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
