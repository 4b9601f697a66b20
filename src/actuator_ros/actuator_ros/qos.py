# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""QoS of the 1 kHz streams, chosen per run mode."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

#: KEEP_LAST depth per mode (docs/concepts/architecture.md#topics quotes these).
REALTIME_DEPTH = 10
SIM_DEPTH = 10000


def control_qos(mode: str) -> QoSProfile:
    """QoS of the 1 kHz streams.

    realtime: BEST_EFFORT (a late sample is worth less than the next one; no retransmission
    stalls), KEEP_LAST 10 so a burst of two or three samples before a callback runs is not
    dropped from the queue. sim: RELIABLE, because lockstep needs every message and a lost one
    would stall the loop, and KEEP_LAST 10000 (10 s of samples): the lockstep does not wait for
    a subscriber off its path (the observer under PI), which fell more than 1000 messages behind
    and lost them from a 1000-deep queue (2 s PI runs: up to 567 substituted pairs in 4 of 14
    runs; 0 of 46 with 10000). A BEST_EFFORT subscriber matches either publisher.
    """
    if mode == 'sim':
        return QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=SIM_DEPTH,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.VOLATILE,
        )
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=REALTIME_DEPTH,
        reliability=ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.VOLATILE,
    )
