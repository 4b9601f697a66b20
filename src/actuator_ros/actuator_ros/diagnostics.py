# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``/diagnostics`` (diagnostic_msgs/DiagnosticArray) from a node: one status per report.

The rules live in actuator_core.health (ROS-free); this publishes what they say on a timer of
the wall (steady) clock, so a sim-time node reports at 2 Hz of wall time whether or not /clock
moves, which is what lets a stopped lockstep show as STALE. The header stamp is the node's own
clock (sim time in sim mode), or for the sim-time joint, which makes that time, its newest
sample's stamp; so a bag lines the reports up with the samples. A node creates one
``NodeDiagnostics`` in its build/configure and destroys it in its drop/cleanup:

    self.diagnostics = NodeDiagnostics(self, HealthMonitor(...), self.health_snapshot)
    ...
    self.diagnostics.destroy()
"""

from __future__ import annotations

import time
from typing import Callable, Optional

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType

from actuator_core.health import REPORT_PERIOD_S, Health, HealthMonitor, Snapshot

#: The topic of the ROS convention (absolute: a namespaced node still reports there).
TOPIC = '/diagnostics'


def to_status(health: Health) -> DiagnosticStatus:
    """DiagnosticStatus of one Health report."""
    return DiagnosticStatus(
        level=bytes([int(health.level)]),
        name=health.name,
        message=health.message,
        hardware_id=health.hardware_id,
        values=[KeyValue(key=k, value=v) for k, v in health.values],
    )


class NodeDiagnostics:
    """Publishes the node's Health on /diagnostics every ``period_s`` of wall time."""

    def __init__(
        self,
        node,
        monitor: HealthMonitor,
        snapshot: Callable[[], Snapshot],
        period_s: float = REPORT_PERIOD_S,
        stamp_ns: Optional[Callable[[], int]] = None,
    ) -> None:
        """Create the publisher and the wall-clock timer (first report after one period).

        ``stamp_ns``: the reports' stamp (None: the node's clock).
        """
        self.node, self.monitor, self.snapshot = node, monitor, snapshot
        self.stamp_ns = stamp_ns
        self.pub = node.create_publisher(DiagnosticArray, TOPIC, 10)
        self.timer = node.create_timer(
            period_s, self.publish, clock=Clock(clock_type=ClockType.STEADY_TIME)
        )
        self.last: Optional[Health] = None

    def publish(self) -> Optional[Health]:
        """Take a snapshot, judge it, publish it; return the Health (None once destroyed).

        A timer event the executor had queued before ``destroy`` may still call this: the node
        has dropped what its snapshot reads by then (a faulted joint), so nothing is reported.
        """
        if self.pub is None:
            return None
        health = self.monitor.update(time.monotonic_ns(), self.snapshot())
        msg = DiagnosticArray()
        if self.stamp_ns is None:
            msg.header.stamp = self.node.get_clock().now().to_msg()
        else:
            stamp = self.stamp_ns()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
        msg.status = [to_status(health)]
        self.pub.publish(msg)
        self.last = health
        return health

    def destroy(self) -> None:
        """Destroy the timer and the publisher (drop/cleanup)."""
        self.node.destroy_timer(self.timer)
        self.node.destroy_publisher(self.pub)
        self.pub = None
