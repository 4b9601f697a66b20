# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""How fast ``GraphGuard`` sees a rogue publisher: ``python -m actuator_bench.guard_probe``.

A victim node subscribes ``joint_states`` with the guard, as the ESO and the controller do; a
rogue process (this module with ``--rogue``) creates a publisher on it and sends messages at
1 kHz, stamped with its wall clock. For each trial the probe reports, on the wall clock both
processes share: when the guard reported the conflict, when the rogue's first message was
sent, and which rogue message had arrived before the report (0: none, the target is < 2).
Rogue kinds: ``matched`` waits until its publisher has matched before it sends (the worst
case for a guard that looks at messages), ``eager`` sends from the moment it exists.
Loopback only (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, as scripts/env.sh sets it).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

MESSAGES = 50


def rogue(kind: str) -> int:
    """Publish MESSAGES joint_states at 1 kHz; print the wall time of the first one."""
    import rclpy
    from sensor_msgs.msg import JointState

    from actuator_ros.qos import control_qos

    rclpy.init()
    node = rclpy.create_node('rogue_probe')
    pub = node.create_publisher(JointState, 'joint_states', control_qos('realtime'))
    if kind == 'matched':
        while pub.get_subscription_count() == 0:
            time.sleep(0.0005)
    first = None
    for k in range(MESSAGES):
        msg = JointState(name=['joint'], position=[float(k)])
        now = time.time_ns()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(now, 1_000_000_000)
        first = now if first is None else first
        pub.publish(msg)
        time.sleep(0.001)
    print(json.dumps({'first_sent_ns': first}), flush=True)
    time.sleep(0.2)
    node.destroy_node()
    rclpy.shutdown()
    return 0


def trial(executor_name: str, kind: str) -> dict:
    """One victim, one rogue: when the conflict was seen against the rogue's messages."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.experimental import EventsExecutor
    from sensor_msgs.msg import JointState

    from actuator_ros.guard import GraphGuard
    from actuator_ros.qos import control_qos

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('victim_probe', context=context)
    seen: dict = {}
    received: list[int] = []

    def on_change(conflict: str) -> None:
        if conflict and 'ns' not in seen:
            seen['ns'] = time.time_ns()
            seen['received_before'] = len(received)

    def on_state(msg: JointState) -> None:
        received.append(int(msg.position[0]))

    guard = GraphGuard(node, on_change)
    node.create_subscription(
        JointState,
        'joint_states',
        on_state,
        control_qos('realtime'),
        event_callbacks=guard.callbacks('joint_states'),
    )
    executor = (EventsExecutor if executor_name == 'events' else SingleThreadedExecutor)(
        context=context
    )
    executor.add_node(node)
    joint = rclpy.create_node('joint_probe', context=context)  # the genuine publisher
    joint.create_publisher(JointState, 'joint_states', control_qos('realtime'))
    end = time.monotonic() + 10.0
    while guard.counts.get('joint_states', 0) < 1 and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.01)
    proc = subprocess.Popen(
        [sys.executable, '-m', 'actuator_bench.guard_probe', '--rogue', kind],
        stdout=subprocess.PIPE,
        text=True,
    )
    end = time.monotonic() + 20.0
    while proc.poll() is None and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.001)
    out = proc.communicate(timeout=10.0)[0]
    executor.shutdown()
    joint.destroy_node()
    node.destroy_node()
    rclpy.shutdown(context=context)
    first = json.loads(out.strip().splitlines()[-1])['first_sent_ns']
    return {
        'executor': executor_name,
        'rogue': kind,
        'seen_minus_first_sent_ms': (seen['ns'] - first) / 1e6 if 'ns' in seen else None,
        'rogue_messages_received_before_seen': seen.get('received_before'),
        'rogue_messages_received': len(received),
    }


def main(argv=None) -> int:
    """Run ``--trials`` trials per executor and rogue kind; print one JSON line each."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--rogue', choices=('matched', 'eager'), help=argparse.SUPPRESS)
    parser.add_argument('--trials', type=int, default=5)
    args = parser.parse_args(argv)
    if args.rogue:
        return rogue(args.rogue)
    for executor_name in ('events', 'single_threaded'):
        for kind in ('matched', 'eager'):
            for _ in range(args.trials):
                print(json.dumps(trial(executor_name, kind)), flush=True)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
