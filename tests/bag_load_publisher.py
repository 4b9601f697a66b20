# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The load publisher of the recorder tests (test_bag_record.py), run as its own process.

``python bag_load_publisher.py N [--reliability R] [--clock]`` publishes N messages at 1 kHz on
each of the five system topics (header.stamp.nanosec = sample index; with ``--clock`` /clock
too, and the stamps in sim time from SIM_T0_S) once every topic has a subscriber, and prints
``published N``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bag_helpers import TOPICS as SYSTEM_TOPICS  # noqa: E402

#: The five system topics and their types ('sensor_msgs/msg/JointState', ...).
TOPICS = dict(SYSTEM_TOPICS.values())
#: The first /clock second of a --clock run.
SIM_T0_S = 1000


def publish(argv: list[str]) -> int:
    """Run the load publisher (see the module docstring)."""
    import importlib

    import rclpy
    from rclpy.node import Node
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    from message_fill import fill_message

    parser = argparse.ArgumentParser()
    parser.add_argument('count', type=int)
    parser.add_argument('--reliability', choices=('reliable', 'best_effort'), default='reliable')
    parser.add_argument(
        '--clock', action='store_true', help='publish /clock and stamp in sim time'
    )
    args = parser.parse_args(argv)
    rclpy.init()
    node = Node('bag_test_publisher')
    qos = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=args.count,
        reliability=ReliabilityPolicy.RELIABLE
        if args.reliability == 'reliable'
        else ReliabilityPolicy.BEST_EFFORT,
    )
    pubs, msgs = [], []
    for topic, msgtype in TOPICS.items():
        module, name = msgtype.rsplit('/', 1)
        cls = getattr(importlib.import_module(module.replace('/', '.')), name)
        pubs.append(node.create_publisher(cls, topic, qos))
        msgs.append(fill_message(cls(), seed=len(msgs) + 1))
    clock_pub = node.create_publisher(Clock, '/clock', 10) if args.clock else None
    deadline = time.monotonic() + 30
    while any(p.get_subscription_count() < 1 for p in pubs):
        if time.monotonic() > deadline:
            print('no subscriber', flush=True)
            return 2
        time.sleep(0.02)
    time.sleep(1.0)
    print('publishing', flush=True)
    start = time.perf_counter()
    for k in range(args.count):
        due = start + k * 1e-3
        while time.perf_counter() < due:
            pass
        if clock_pub is not None:
            clock = Clock()
            clock.clock.sec, clock.clock.nanosec = SIM_T0_S + k // 1000, (k % 1000) * 1_000_000
            clock_pub.publish(clock)
            sec, nanosec = clock.clock.sec, clock.clock.nanosec
        else:
            sec, nanosec = 1, k
        for pub, msg in zip(pubs, msgs):
            msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
            pub.publish(msg)
    print(f'published {args.count} in {time.perf_counter() - start:.3f} s', flush=True)
    time.sleep(1.0)
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == '__main__':
    raise SystemExit(publish(sys.argv[1:]))
