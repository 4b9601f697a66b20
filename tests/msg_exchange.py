# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Publisher / subscriber process for the message exchange tests (run with the venv's python).

msg_exchange.py pub --package actuator_msgs --types A,B --seed 7
    publishes one message of each type, filled by message_fill.fill_message(seed + i),
    on topic exchange/<Type> (reliable, transient local, depth 1), prints
    "READY" and keeps serving them until SIGINT, then exits 0.
msg_exchange.py sub --package actuator_msgs --types A,B --timeout 30
    waits for one message of each type and prints "RECEIVED <json>", the leaves of
    every message (message_fill.message_leaves), then exits 0; exits 2 on timeout.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import rclpy  # noqa: E402
from rclpy.executors import ExternalShutdownException  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402

import message_fill  # noqa: E402

QOS = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)


def topic_of(type_name: str) -> str:
    return f'exchange/{type_name}'


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument('mode', choices=('pub', 'sub'))
    parser.add_argument('--package', default='actuator_msgs')
    parser.add_argument('--types', required=True, help='comma-separated message type names')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--timeout', type=float, default=30.0)
    args = parser.parse_args(argv)

    module = importlib.import_module(f'{args.package}.msg')
    types = [t for t in args.types.split(',') if t]
    rclpy.init()
    node = rclpy.create_node(f'msg_exchange_{args.mode}')
    try:
        if args.mode == 'pub':
            publishers = []
            for i, name in enumerate(types):
                cls = getattr(module, name)
                pub = node.create_publisher(cls, topic_of(name), QOS)
                pub.publish(message_fill.fill_message(cls(), args.seed + i))
                publishers.append(pub)
            print('READY', flush=True)
            rclpy.spin(node)
            return 0

        received = {}

        def make_callback(name):
            def callback(msg):
                received.setdefault(name, message_fill.message_leaves(msg))

            return callback

        subscriptions = [
            node.create_subscription(
                getattr(module, name), topic_of(name), make_callback(name), QOS
            )
            for name in types
        ]
        print('SUBSCRIBED', len(subscriptions), flush=True)
        deadline = time.monotonic() + args.timeout
        while len(received) < len(types) and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        print('RECEIVED ' + json.dumps(received, sort_keys=True), flush=True)
        return 0 if len(received) == len(types) else 2
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
