# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Probe: what an rclpy action server costs a 1 kHz echo on the executor the node uses.

    python -m actuator_bench.action_executor_probe [--seconds S] [--executors ...]

The design question of the controller's goal interface (goal_interface.py): put the
FollowJointTrajectory server on the control node's executor, on a node and thread of its own
in the same process, or nowhere. A child process plays the control node: a 1 kHz ping it
answers at once (its callback is the 1 kHz path), on ``--executors``, with the server ``same``
(on that node and executor), ``thread`` (its own node, SingleThreadedExecutor, thread: the
design taken) or ``none``. This process pings it at 1 kHz and measures each round trip; for
the second half of each run it sends a 50-point goal every 100 ms, each executed for 300 ms
with feedback at 20 Hz. Printed per variant and phase: round trip p50/p99/max [us] and the
child's CPU [% of one core]. Nothing is asserted; run it on a quiet machine for figures.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from typing import Optional, Sequence

import numpy as np
import psutil

VARIANTS = ('none', 'same', 'thread')
PING, PONG = 'probe/ping', 'probe/pong'
ACTION = 'probe/follow_joint_trajectory'


def serve(executor_kind: str, server: str) -> int:
    """Run the child: answer pings; the action server where ``server`` says."""
    import threading

    import rclpy
    from control_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionServer
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.task import Future
    from std_msgs.msg import Header

    from actuator_ros.runner import make_executor

    rclpy.init()
    node = Node('probe_loop')
    pong = node.create_publisher(Header, PONG, 10)
    node.create_subscription(Header, PING, pong.publish, 10)

    def add_server(owner) -> None:
        """Add the server as goal_interface runs it: execute awaits a future a timer ends."""
        running: list = []  # [handle, future, ticks left]

        async def execute(handle):
            done = Future()
            running.append([handle, done, 6])  # 300 ms
            return await done

        def monitor() -> None:
            for entry in list(running):
                handle, done, left = entry
                handle.publish_feedback(FollowJointTrajectory.Feedback())
                entry[2] -= 1
                if entry[2] <= 0:
                    running.remove(entry)
                    handle.succeed()
                    done.set_result(FollowJointTrajectory.Result())

        ActionServer(owner, FollowJointTrajectory, ACTION, execute_callback=execute)
        owner.create_timer(0.05, monitor)

    executor = make_executor(executor_kind)
    executor.add_node(node)
    if server == 'same':
        add_server(node)
    elif server == 'thread':
        goals = Node('probe_goals')
        add_server(goals)
        goal_executor = SingleThreadedExecutor()
        goal_executor.add_node(goals)

        def spin_goals() -> None:
            try:
                goal_executor.spin()
            except Exception:  # noqa: BLE001 - the context shut down at the end of the run
                pass

        threading.Thread(target=spin_goals, daemon=True).start()
    print('ready', flush=True)
    try:
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass  # the driver's terminate: the run is over
    return 0


def drive(executor_kind: str, server: str, seconds: float) -> dict:
    """Start the child, ping it at 1 kHz, send goals in the second half; its figures."""
    import rclpy
    from control_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionClient
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import Header
    from trajectory_msgs.msg import JointTrajectoryPoint

    child = subprocess.Popen(
        [
            sys.executable,
            '-m',
            'actuator_bench.action_executor_probe',
            'serve',
            executor_kind,
            server,
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert child.stdout is not None  # stdout=PIPE
    child.stdout.readline()
    context = Context()
    rclpy.init(context=context)
    node = Node('probe_driver', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    sent: dict[int, int] = {}
    trips: list[tuple[float, float]] = []

    def on_pong(msg: Header) -> None:
        if msg.stamp.nanosec in sent:
            trip_us = (time.perf_counter_ns() - sent.pop(msg.stamp.nanosec, 0)) / 1e3
            trips.append((time.monotonic(), trip_us))

    node.create_subscription(Header, PONG, on_pong, 10)
    ping = node.create_publisher(Header, PING, 10)
    client = ActionClient(node, FollowJointTrajectory, ACTION) if server != 'none' else None
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.joint_names = ['joint']
    goal.trajectory.points = [JointTrajectoryPoint(positions=[0.01 * k]) for k in range(50)]
    end = time.monotonic() + 3.0
    while ping.get_subscription_count() < 1 and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.01)
    if client is not None:
        client.wait_for_server(timeout_sec=5.0)
    process = psutil.Process(child.pid)
    start = time.monotonic()
    half = start + seconds / 2
    cpu = {}
    process.cpu_percent()
    next_ping, next_goal, k = start, half, 0
    while time.monotonic() < start + seconds:
        now = time.monotonic()
        if now >= next_ping:
            k += 1
            msg = Header()
            msg.stamp.nanosec = k
            sent[k] = time.perf_counter_ns()
            ping.publish(msg)
            next_ping += 1e-3
        if client is not None and now >= next_goal:
            client.send_goal_async(goal)
            next_goal += 0.1
        if 'idle' not in cpu and now >= half:
            cpu['idle'] = process.cpu_percent()
        executor.spin_once(timeout_sec=max(0.0, min(next_ping, next_goal) - time.monotonic()))
    cpu['goals'] = process.cpu_percent()
    child.terminate()
    child.wait(timeout=10)
    node.destroy_node()
    context.try_shutdown()
    out = {}
    for phase, lo, hi in (('idle', start, half), ('goals', half, start + seconds)):
        rtt = np.array([r for t, r in trips if lo <= t < hi])
        out[phase] = {
            'answered': int(rtt.size),
            'rtt_us_p50': float(np.percentile(rtt, 50)) if rtt.size else None,
            'rtt_us_p99': float(np.percentile(rtt, 99)) if rtt.size else None,
            'rtt_us_max': float(rtt.max()) if rtt.size else None,
            'cpu_percent': cpu.get(phase),
        }
    return out


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Probe every variant, print the table."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] == ['serve']:
        return serve(args[1], args[2])
    parser = argparse.ArgumentParser(
        prog='action_executor_probe', description=__doc__.splitlines()[0]
    )
    parser.add_argument('--seconds', type=float, default=6.0, help='each variant [s]')
    parser.add_argument(
        '--executors',
        nargs='+',
        default=['events', 'single_threaded'],
        choices=('events', 'single_threaded'),
    )
    parser.add_argument('--variants', nargs='+', default=list(VARIANTS), choices=VARIANTS)
    options = parser.parse_args(args)
    print(
        f'{"executor":<16} {"server":<7} {"phase":<6} {"answered":>8} {"p50 us":>8} '
        f'{"p99 us":>8} {"max us":>9} {"CPU %":>6}'
    )
    for kind in options.executors:
        for variant in options.variants:
            figures = drive(kind, variant, options.seconds)
            for phase, f in figures.items():
                print(
                    f'{kind:<16} {variant:<7} {phase:<6} {f["answered"]:>8} '
                    f'{f["rtt_us_p50"] or 0:>8.0f} {f["rtt_us_p99"] or 0:>8.0f} '
                    f'{f["rtt_us_max"] or 0:>9.0f} {f["cpu_percent"] or 0:>6.1f}',
                    flush=True,
                )
    return 0


if __name__ == '__main__':
    sys.exit(main())
