# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Middleware floor: what one message hop costs on this machine with no control code at all.

Two processes stand in for two of our nodes. ``source`` publishes an
``actuator_msgs/CurrentCommand`` on an absolute grid (as the plant samples) and ``echo``
republishes each one unchanged (as the ESO and controller answer a sample). The source logs every
round trip; one hop is taken as half of it. The echo's CPU is the price of one subscription and one
publication per sample; each of our loop nodes handles two or three of each. The benchmark
(``bench``) runs this before the closed loop, so its latency and CPU targets can be read against
what the middleware alone costs here.

    python -m actuator_bench.floor echo   [--ros-args -p thread_priority:=N ...]
    python -m actuator_bench.floor source --ros-args -p thread_priority:=N -p duration_s:=10
        -p output:=rtt.npz
"""

from __future__ import annotations

import sys
import threading
import time

import numpy as np
from rclpy.node import Node

from actuator_msgs.msg import CurrentCommand
from actuator_ros.parameters import declare_number, declare_text
from actuator_ros.process_member import ProcessMember
from actuator_ros.qos import control_qos
from actuator_ros.runner import run_node

PING, PONG = 'floor/ping', 'floor/pong'


class EchoNode(Node, ProcessMember):
    """Republishes every message of floor/ping on floor/pong, as it arrived."""

    def __init__(self) -> None:
        """One subscription, one publisher, the loop's real-time QoS."""
        super().__init__('floor_echo')
        qos = control_qos('realtime')
        self.pub = self.create_publisher(CurrentCommand, PONG, qos)
        self.create_subscription(CurrentCommand, PING, self.pub.publish, qos)


class SourceNode(Node, ProcessMember):
    """Publishes stamped messages on a fixed grid and records the round trip of each echo."""

    def __init__(self) -> None:
        """Parameters: rate_hz, duration_s, output (.npz of the round trips)."""
        super().__init__('floor_source')
        self.period_ns = int(
            round(
                1e9
                / declare_number(self, 'rate_hz', 1000.0, 1.0, 1.0e4, 'Hz', 'messages per second')
            )
        )
        self.duration_s = declare_number(
            self, 'duration_s', 10.0, 0.1, 3600.0, 's', 'measured span'
        )
        self.output = declare_text(self, 'output', '', 'file (.npz) for the round-trip times')
        qos = control_qos('realtime')
        self.pub = self.create_publisher(CurrentCommand, PING, qos)
        self.create_subscription(CurrentCommand, PONG, self.on_echo, qos)
        self.rtt_ns: list[int] = []
        self.sent = 0
        self.finished = False
        self.error: str | None = None
        self.ready_since_ns: int | None = None
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._loop, name='source', daemon=True)
        self.timer = self.create_timer(0.1, self.on_start_check)

    def on_start_check(self) -> None:
        """Start the source thread once the echo has been matched for 0.5 s."""
        if self.thread.is_alive() or self.finished:
            return
        if self.pub.get_subscription_count() < 1 or self.count_publishers(PONG) < 1:
            return
        now = time.monotonic_ns()
        if self.ready_since_ns is None:
            self.ready_since_ns = now
        elif now - self.ready_since_ns >= 500_000_000:
            self.get_logger().info('sampling started')
            self.thread.start()

    def _loop(self) -> None:
        """Publish on an absolute grid of the system clock until duration_s has passed."""
        try:
            msg = CurrentCommand()
            start = time.time_ns() + self.period_ns
            count = int(self.duration_s * 1e9) // self.period_ns
            for k in range(count):
                if self.stop.is_set():
                    break
                wait_ns = start + k * self.period_ns - time.time_ns()
                if wait_ns > 0:
                    time.sleep(wait_ns * 1e-9)
                now = time.time_ns()
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(now, 1_000_000_000)
                self.pub.publish(msg)
                self.sent += 1
            time.sleep(0.1)  # the last echoes
        except Exception as exc:  # noqa: BLE001 - reported by run_node
            self.error = f'source thread failed: {exc!r}'
        self.finished = True

    def on_echo(self, msg: CurrentCommand) -> None:
        """Round trip of one message [ns]."""
        self.rtt_ns.append(
            time.time_ns() - (msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
        )

    def halt(self) -> None:
        """Stop the thread; write the round trips and the sent count (ProcessMember)."""
        self.stop.set()
        if self.thread.is_alive():
            self.thread.join(timeout=1.0)
        if self.output:
            np.savez(
                self.output,
                rtt_ns=np.asarray(self.rtt_ns, dtype=np.int64),
                sent=np.int64(self.sent),
            )
        self.get_logger().info(f'sent {self.sent}, echoed {len(self.rtt_ns)}')


def main(argv: list[str] | None = None) -> int:
    """``python -m actuator_bench.floor echo|source [run_node options]``."""
    args = sys.argv[1:] if argv is None else list(argv)
    roles: dict[str, tuple[str, str, type[EchoNode] | type[SourceNode], str]] = {
        'echo': (
            'floor echo',
            'Echo node of the middleware floor benchmark.',
            EchoNode,
            'floor_echo',
        ),
        'source': (
            'floor source',
            'Source node of the middleware floor benchmark.',
            SourceNode,
            'floor_source',
        ),
    }
    if not args or args[0] not in roles:
        print(
            f'usage: python -m actuator_bench.floor {{{",".join(roles)}}} [options]',
            file=sys.stderr,
        )
        return 2
    prog, description, node_class, name = roles[args[0]]
    return run_node(prog, description, lambda settings: node_class(), name, args[1:])


if __name__ == '__main__':
    raise SystemExit(main())
