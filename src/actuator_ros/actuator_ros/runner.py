# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""main() of every node: real-time settings, rclpy.init, the node, autostart, spin, clean exit.

Exit codes: 0 after SIGINT or SIGTERM at any moment (no traceback) or when the node ended the
run itself (``finished``); 1 when it failed (``error``, logged) or could not be built or
released (``process_member.MemberError``: one line ``prog: error: ...`` on stderr); 2 with one
line on stderr for a refused parameter, an unreadable parameter file or a refused configure at
autostart.
"""

from __future__ import annotations

import argparse
import faulthandler
import gc
import os
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

from actuator_ros.middleware import TransportChoice, installed_profile, realtime_transport
from actuator_ros.parameters import ParameterError
from actuator_ros.process_member import SETTLE_LIMIT_S, MemberError, ProcessMember
from actuator_ros.realtime import (
    PUBLICATION_MODE_VARIABLE,
    RealtimeSettings,
    in_sim_time,
    pre_init_settings,
    publication_mode,
)

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


def spin_until(executor, done: Callable[[], bool], wake=None) -> None:
    """Run the executor until ``done()``.

    Not executor.spin(): EventsExecutor.spin() does not return on shutdown (rclpy 7.1 here).
    spin_until_future_complete on a future that is not complete runs the executor in C++ for
    up to 0.1 s at a time (20 % less CPU than a spin_once loop, measured), and ``done`` is
    checked in between. ``wake``, a Future the caller completes with its stop request (the
    signal handler of ``run_node``), ends that wait at once: without it a stop came up to
    0.1 s late (measured 0.108 s for the controller).
    """
    future = rclpy.task.Future() if wake is None else wake
    while not done() and rclpy.ok():
        executor.spin_until_future_complete(future, timeout_sec=0.1)


def run_node(
    prog: str,
    description: str,
    node_factory: Callable[[RealtimeSettings], ProcessMember],
    node_name: str,
    argv: Sequence[str] | None = None,
) -> int:
    """Start a node the way ``ros2 run`` does and run it until a signal or its own end."""
    return run_nodes(prog, description, [node_factory], node_name, argv)


def run_nodes(
    prog: str,
    description: str,
    node_factories: Sequence[Callable[[RealtimeSettings], ProcessMember]],
    settings_node: str,
    argv: Sequence[str] | None = None,
    own_arguments: Callable[[argparse.ArgumentParser], None] | None = None,
) -> int:
    """Run one or several nodes in this process on one executor, until a signal or an end.

    The process's real-time settings are ``settings_node``'s (one policy per process). The run
    ends when any node ended it (``finished``) or failed (``error``); every node is then
    halted, left to settle, its RELIABLE subscribers given time to acknowledge, and released.
    Every node is a ``ProcessMember`` (process_member.py says the order); no attribute probing.
    """
    args = sys.argv[1:] if argv is None else list(argv)
    settings = _parse_settings(prog, description, args, settings_node, own_arguments)
    if settings is None:
        return 2
    stop = threading.Event()
    wake = rclpy.task.Future()
    _stop_on_signals(stop, wake)
    refused = settings.apply()  # before rclpy.init: the middleware's threads inherit it
    transport = _prepare_middleware(args, settings_node)
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # rcl's RCLError: an unparsable parameter file, a bad --ros-args
        print(f'{prog}: ROS arguments refused: {str(exc).splitlines()[0]}', file=sys.stderr)
        return 2
    nodes: list = []
    executor = None
    try:
        code = _build_nodes(prog, node_factories, settings, nodes)
        if code is not None:
            return code
        _log_settings(nodes[0], transport, refused, settings)
        share_clock_subscription(nodes)
        executor = make_executor(settings.executor)
        for node in nodes:
            executor.add_node(node)
        for node in nodes:
            if not node.autostart():
                print(
                    f'{prog}: autostart of {node.get_name()}: configure or activate failed '
                    '(see the log above)',
                    file=sys.stderr,
                )
                return 2
        # Everything built so far lives for the whole run: move it out of the collector's view,
        # so a collection in the 1 kHz path scans only what the loop itself allocates.
        gc.collect()
        gc.freeze()
        spin_until(executor, lambda: stop.is_set() or any(n.finished for n in nodes), wake)
        failed = [n for n in nodes if n.error]
        for node in failed:
            node.get_logger().error(node.error)
        return max(1 if failed else 0, _end(prog, nodes, executor))
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if nodes:  # an early return or an exception: the same end (_end empties ``nodes``)
            _end(prog, nodes, executor)
        if rclpy.ok():
            rclpy.shutdown()


def _parse_settings(
    prog: str,
    description: str,
    args: list[str],
    settings_node: str,
    own_arguments: Callable[[argparse.ArgumentParser], None] | None,
) -> RealtimeSettings | None:
    """Parse the command line; return the real-time settings (None: refused, said on stderr)."""
    try:
        own_args = rclpy.utilities.remove_ros_args(args)
    except (
        Exception
    ) as exc:  # rcl's RCLInvalidROSArgsError: an unparsable params file, bad --ros-args
        print(f'{prog}: ROS arguments refused: {str(exc).splitlines()[0]}', file=sys.stderr)
        return None
    parser = argparse.ArgumentParser(
        prog=prog,
        description=description,
        epilog='ROS arguments: --ros-args -p name:=value --params-file file.yaml; '
        'real-time: -p thread_priority:=50 -p cpu_affinity:=1 -p executor:=events',
    )
    if own_arguments is not None:
        own_arguments(parser)
    parser.parse_args(own_args)
    settings = pre_init_settings(args, settings_node)
    problems = settings.problems()
    if problems:
        print(f'{prog}: {problems[0]}', file=sys.stderr)
        return None
    return settings


def _stop_on_signals(stop: threading.Event, wake: rclpy.task.Future) -> None:
    """Stop on SIGINT or SIGTERM (set ``stop``, complete ``wake``); dump stacks on SIGUSR1."""

    def request_stop(*_) -> None:
        stop.set()
        if not wake.done():
            wake.set_result(True)  # spin_until returns now, not at its next 0.1 s check

    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, request_stop)
    faulthandler.register(signal.SIGUSR1, all_threads=True)  # kill -USR1: every thread's stack


def _prepare_middleware(args: list[str], settings_node: str) -> TransportChoice | None:
    """Set the middleware's environment before rclpy.init; return the real-time transport."""
    sim = in_sim_time(args, settings_node)
    # read by rmw_fastrtps when rclpy.init creates it
    os.environ.setdefault(
        PUBLICATION_MODE_VARIABLE,
        publication_mode(sim, fifo=os.sched_getscheduler(0) == os.SCHED_FIFO),
    )
    transport = None
    if not sim:  # a lockstep has no deadline to miss
        transport = realtime_transport(os.environ, installed_profile())
        transport.apply(os.environ)
    return transport


def _build_nodes(
    prog: str,
    node_factories: Sequence[Callable[[RealtimeSettings], ProcessMember]],
    settings: RealtimeSettings,
    nodes: list,
) -> int | None:
    """Build each node into ``nodes``; return the exit code when one is refused (None: built)."""
    try:
        for factory in node_factories:
            node = factory(settings)
            if not isinstance(node, ProcessMember):  # a programming error: said plainly
                node.destroy_node()
                raise TypeError(f'{type(node).__name__} is not a ProcessMember')
            nodes.append(node)
    except ParameterError as exc:
        print(f'{prog}: {exc}', file=sys.stderr)
        return 2
    except MemberError as exc:  # a node that could not be built for what it was given
        print(f'{prog}: error: {exc}', file=sys.stderr)
        return 1
    return None


def _log_settings(
    first: Node,
    transport: TransportChoice | None,
    refused: str | None,
    settings: RealtimeSettings,
) -> None:
    """Log on ``first`` the transport's note and the real-time settings (or what was refused)."""
    if transport is not None and transport.note:
        say = first.get_logger().warning if transport.warning else first.get_logger().info
        say(transport.note)
    if refused:
        first.get_logger().warning(refused)
    elif settings.thread_priority:
        first.get_logger().info(
            f'running under SCHED_FIFO priority {settings.thread_priority} (all threads)'
        )


def settle(executor, nodes: Sequence[ProcessMember], limit_s: float = SETTLE_LIMIT_S) -> bool:
    """After the halt, spin until every node has taken what was delivered (``settled``).

    Returns False when ``limit_s`` passed first.
    """
    end = time.monotonic() + limit_s
    while not all(n.settled() for n in nodes):
        if time.monotonic() >= end or not rclpy.ok():
            return False
        executor.spin_once(timeout_sec=0.05)
    return True


def _end(prog: str, nodes: list, executor=None) -> int:
    """End ``nodes`` in ProcessMember's order; ``nodes`` is emptied, so it is done once.

    A second Ctrl-C must not cut it short. Halt (a joint's last safe-stop command goes out),
    settle (with the executor, once there is one), acknowledgements, release, destruction.
    Returns 1 when a release failed (its one line printed), else 0.
    """
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.SIG_IGN)
    for node in nodes:
        node.halt()
    if executor is not None:
        settle(executor, nodes)
    code = 0
    deadline = time.monotonic() + ACK_TIMEOUT_S
    for node in nodes:  # before the publishers are destroyed
        wait_for_acknowledgements(node, max(0.0, deadline - time.monotonic()))
    for node in nodes:
        try:
            node.release()
        except MemberError as exc:
            print(f'{prog}: error: {exc}', file=sys.stderr, flush=True)
            code = 1
        node.destroy_node()
    nodes.clear()
    return code


def share_clock_subscription(nodes: Sequence[Node]) -> int:
    """Let the sim-time nodes of one process follow /clock through one subscription.

    rclpy gives every node with ``use_sim_time`` a /clock subscription of its own; in a
    composed lockstep each of them costs a take and a Python callback per sample. The first
    such node's time source keeps its subscription and drives the others' clocks; theirs are
    dropped (a follower set to ``use_sim_time`` false reads the system clock, as rclpy does).
    Returns how many subscriptions were dropped.
    """
    sim = [n for n in nodes if n.get_parameter('use_sim_time').value]
    for node in sim[1:]:
        node._time_source.detach_node()  # rclpy 7.1: the node's own TimeSource (private)
        # rclpy types get_clock() as Clock; a node's clock is a ROSClock
        sim[0]._time_source.attach_clock(node.get_clock())  # type: ignore[arg-type]
    return max(0, len(sim) - 1)


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
