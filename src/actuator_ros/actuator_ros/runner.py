# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""main() of every node: real-time settings, rclpy.init, the node, autostart, spin, clean exit.

Exit codes: 0 after SIGINT or SIGTERM at any moment (no traceback) or when the node ended the
run itself (``finished``); 1 when it failed (``error``, logged); 2 with one line on stderr for
a refused parameter, an unreadable parameter file or a refused configure at autostart.
"""

from __future__ import annotations

import argparse
import gc
import signal
import sys
import threading
import time
from typing import Callable, Sequence

import rclpy
import rclpy.task
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from actuator_ros.parameters import ParameterError
from actuator_ros.realtime import RealtimeSettings, pre_init_settings

#: Longest wait at shutdown for RELIABLE subscribers to acknowledge what was published [s]. A
#: sample the transport dropped is resent only when the reader answers the writer's heartbeat
#: (Fast DDS: every 3 s by default).
ACK_TIMEOUT_S = 5.0


def make_executor(kind: str):
    """Return the executor by name.

    'events' (rclpy.experimental.EventsExecutor) or 'single_threaded'.
    """
    if kind == 'events':
        from rclpy.experimental import EventsExecutor

        return EventsExecutor()
    return SingleThreadedExecutor()


def spin_until(executor, done: Callable[[], bool]) -> None:
    """Run the executor until ``done()``.

    Not executor.spin(): EventsExecutor.spin() does not return on shutdown (rclpy 7.1 here).
    spin_until_future_complete on a future that never completes runs the executor in C++ for
    up to 0.1 s at a time (20 % less CPU than a spin_once loop, measured), and ``done`` is
    checked in between, so a stop request is answered within 0.1 s.
    """
    never = rclpy.task.Future()
    while not done() and rclpy.ok():
        executor.spin_until_future_complete(never, timeout_sec=0.1)


def run_node(
    prog: str,
    description: str,
    node_factory: Callable[[RealtimeSettings], Node],
    node_name: str,
    argv: Sequence[str] | None = None,
) -> int:
    """Start a node the way ``ros2 run`` does and run it until a signal or its own end."""
    args = sys.argv[1:] if argv is None else list(argv)
    try:
        own_args = rclpy.utilities.remove_ros_args(args)
    except (
        Exception
    ) as exc:  # rcl's RCLInvalidROSArgsError: an unparsable params file, bad --ros-args
        print(f'{prog}: ROS arguments refused: {str(exc).splitlines()[0]}', file=sys.stderr)
        return 2
    argparse.ArgumentParser(
        prog=prog,
        description=description,
        epilog='ROS arguments: --ros-args -p name:=value --params-file file.yaml; '
        'real-time: -p thread_priority:=50 -p cpu_affinity:=1 -p executor:=events',
    ).parse_args(own_args)
    settings = pre_init_settings(args, node_name)
    problems = settings.problems()
    if problems:
        print(f'{prog}: {problems[0]}', file=sys.stderr)
        return 2
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    refused = settings.apply()  # before rclpy.init: the middleware's threads inherit it
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # rcl's RCLError: an unparsable parameter file, a bad --ros-args
        print(f'{prog}: ROS arguments refused: {str(exc).splitlines()[0]}', file=sys.stderr)
        return 2
    node = None
    try:
        try:
            node = node_factory(settings)
        except ParameterError as exc:
            print(f'{prog}: {exc}', file=sys.stderr)
            return 2
        if refused:
            node.get_logger().warning(refused)
        elif settings.thread_priority:
            node.get_logger().info(
                f'running under SCHED_FIFO priority {settings.thread_priority} (all threads)'
            )
        executor = make_executor(settings.executor)
        executor.add_node(node)
        if hasattr(node, 'autostart') and not node.autostart():
            print(
                f'{prog}: autostart: configure or activate failed (see the log above)',
                file=sys.stderr,
            )
            return 2
        # Everything built so far lives for the whole run: move it out of the collector's view,
        # so a collection in the 1 kHz path scans only what the loop itself allocates.
        gc.collect()
        gc.freeze()
        spin_until(executor, lambda: stop.is_set() or getattr(node, 'finished', False))
        if getattr(node, 'error', None):
            node.get_logger().error(node.error)
            return 1
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if node is not None:
            for signum in (signal.SIGINT, signal.SIGTERM):
                signal.signal(
                    signum, signal.SIG_IGN
                )  # a second Ctrl-C must not cut the clean-up short
            managed = hasattr(node, 'halt')
            if managed:
                node.halt()  # stop acting (its last safe-stop command goes out)
            elif hasattr(node, 'close'):
                node.close()  # a plain node (the benchmark's floor nodes)
            wait_for_acknowledgements(node)  # before the publishers are destroyed
            if managed:
                node.on_shutdown(None)  # drop what it built
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


def wait_for_acknowledgements(node: Node, timeout_s: float = ACK_TIMEOUT_S) -> bool:
    """Before exit: let RELIABLE subscribers receive all this node published.

    Such as the sim-mode recorder. A process that exits takes the samples it has not delivered with
    it, and at the end of a sim run the recorder is the furthest behind (2 s runs ended with the
    bag missing the last 68-159 samples). BEST_EFFORT publishers return at once. Logs, and returns
    False, when a topic stayed unacknowledged.
    """
    deadline = time.monotonic() + timeout_s
    unacked = []
    for pub in list(node.publishers):
        left = max(0.0, deadline - time.monotonic())
        if not pub.wait_for_all_acked(Duration(seconds=left)):
            unacked.append(pub.topic_name)
    if unacked:
        node.get_logger().warning(
            f'exiting with samples not acknowledged by every subscriber on '
            f'{", ".join(unacked)} after {timeout_s:g} s: a RELIABLE subscriber (the recorder?) '
            'missed them'
        )
    return not unacked
