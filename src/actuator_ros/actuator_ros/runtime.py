"""ROS plumbing shared by the nodes: parameters from specs, QoS by run mode, and a clean main().

Imported by nodes only; the math modules never import it (or rclpy).
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import signal
import sys
import threading
import time
from typing import Any, Callable, Sequence

import rclpy
import rclpy.task
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from actuator_core.params import build, iter_specs, range_text

#: Run modes: wall-clock 1 kHz timers, or lockstep on the plant's /clock.
MODES = ('realtime', 'sim')


class ParameterError(ValueError):
    """A parameter value was refused; the message names the parameter and its valid range."""


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
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10000, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)


def _descriptor(name: str, meta: dict, default: Any, read_only: bool) -> ParameterDescriptor:
    """Descriptor with description, unit, valid range and, where finite, an enforced range."""
    text = meta['description']
    if not isinstance(default, (bool, str)):
        text += f' [{meta["unit"] or "-"}], valid {range_text(meta)}'
    descriptor = ParameterDescriptor(name=name, description=text, read_only=read_only)
    low, high = meta['low'], meta['high']
    if isinstance(default, bool) or isinstance(default, str):
        return descriptor
    if isinstance(default, int) and math.isfinite(low) and math.isfinite(high):
        descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    elif isinstance(default, float) and math.isfinite(low) and math.isfinite(high):
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
    return descriptor


def declare_spec_parameters(node: Node, cls: type, prefix: str = '', read_only: bool = True) -> Any:
    """Declare every spec'd field of dataclass ``cls`` as ``prefix + dotted name`` and build ``cls``.

    Raises ParameterError naming the parameter and its valid range when a value given by
    YAML or ``-p`` is out of range (rclpy's own range check, or the dataclass' checks).
    """
    values: dict[str, Any] = {}
    for name, f in iter_specs(cls):
        default = f.default
        full = prefix + name
        try:
            values[name] = node.declare_parameter(full, default, _descriptor(full, f.metadata, default,
                                                                               read_only)).value
        except Exception as exc:  # rclpy raises InvalidParameterValueException / InvalidParameterTypeException
            raise ParameterError(f'parameter {full!r} refused: valid {range_text(f.metadata)} '
                                 f'({f.metadata["description"]}); {exc}') from None
    try:
        return build(cls, values)
    except (ValueError, TypeError) as exc:
        raise ParameterError(f'{prefix}{exc}') from None


def declare_choice(node: Node, name: str, default: str, choices: Sequence[str], description: str) -> str:
    """Declare a read-only string parameter limited to ``choices``; raise ParameterError otherwise."""
    value = node.declare_parameter(name, default, ParameterDescriptor(
        name=name, description=f'{description}; one of {", ".join(choices)}', read_only=True)).value
    if value not in choices:
        raise ParameterError(f'parameter {name!r} = {value!r} refused: must be one of {", ".join(choices)}')
    return value


def declare_number(node: Node, name: str, default: float | int, low: float, high: float, unit: str,
                   description: str) -> float | int:
    """Declare a read-only number parameter (an int when ``default`` is) in [low, high]; raise ParameterError otherwise."""
    meta = {'description': description, 'unit': unit, 'low': low, 'high': high, 'low_open': False}
    try:
        value = node.declare_parameter(name, default, _descriptor(name, meta, default, True)).value
    except Exception as exc:
        raise ParameterError(f'parameter {name!r} refused: valid {range_text(meta)} ({description}); {exc}') from None
    if not (isinstance(value, (int, float)) and math.isfinite(value) and low <= value <= high):
        raise ParameterError(f'parameter {name!r} = {value} refused: valid {range_text(meta)} ({description})')
    return value if isinstance(default, int) else float(value)


def make_executor(kind: str):
    """The executor by name: 'events' (rclpy.experimental.EventsExecutor) or 'single_threaded'."""
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor()
    return SingleThreadedExecutor()


def run_node(prog: str, description: str, node_factory: Callable[[], Node], argv: Sequence[str] | None = None) -> int:
    """main() of every node: --help, init, build the node (refusing bad parameters), spin, clean exit.

    SIGINT and SIGTERM set a stop flag (rclpy's own handlers are off, so the context stays
    valid), and a node may end the run itself by setting ``finished``: the loop ends, the node's
    ``close()`` runs and may still log, then the node is destroyed and the process exits 0 with
    no traceback, or 1 when the node set ``error`` (a message, logged). A refused parameter exits 2 with
    one line naming it.
    """
    args = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(prog=prog, description=description,
                                     epilog='ROS arguments: --ros-args -p name:=value --params-file file.yaml')
    parser.add_argument('--executor', choices=('events', 'single_threaded'), default='events',
                        help='rclpy executor (default: events, the lower-latency EventsExecutor)')
    parser.add_argument('--rt-priority', type=int, default=0, metavar='N',
                        help='run under SCHED_FIFO at priority N (1-99; 0 = normal scheduling)')
    parser.add_argument('--cpus', default='', metavar='LIST',
                        help='pin the process to these CPUs, e.g. "1" or "0,1" (default: no pinning)')
    parsed = parser.parse_args(rclpy.utilities.remove_ros_args(args))
    if not 0 <= parsed.rt_priority <= 99:
        parser.error('--rt-priority must be in [0, 99]')
    if parsed.cpus:
        try:
            os.sched_setaffinity(0, {int(c) for c in parsed.cpus.split(',')})
        except (ValueError, OSError) as exc:
            parser.error(f'--cpus {parsed.cpus!r} refused: {exc}')
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    # Before rclpy.init: the middleware's threads (Fast DDS receive and event threads), which
    # every message passes through, inherit the policy only if it is set before they exist.
    priority_refused = set_realtime_priority(parsed.rt_priority) if parsed.rt_priority else None
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        try:
            node = node_factory()
        except ParameterError as exc:
            print(f'{prog}: {exc}', file=sys.stderr)
            return 2
        if priority_refused:
            node.get_logger().warning(priority_refused)
        elif parsed.rt_priority:
            node.get_logger().info(f'running under SCHED_FIFO priority {parsed.rt_priority} (all threads)')
        # Everything built so far lives for the whole run: move it out of the collector's view,
        # so a collection in the 1 kHz path scans only what the loop itself allocates.
        gc.collect()
        gc.freeze()
        executor = make_executor(parsed.executor)
        executor.add_node(node)
        # Not executor.spin(): EventsExecutor.spin() does not return on shutdown (rclpy 7.1 here).
        # spin_until_future_complete on a future that never completes runs the executor in C++
        # for up to 0.1 s at a time (20 % less CPU than a spin_once loop, measured), and the stop
        # flag is checked in between.
        never = rclpy.task.Future()
        while not stop.is_set() and rclpy.ok() and not getattr(node, 'finished', False):
            executor.spin_until_future_complete(never, timeout_sec=0.1)
        error = getattr(node, 'error', None)
        if error:
            node.get_logger().error(error)
            return 1
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if node is not None:
            close = getattr(node, 'close', None)
            if close is not None:
                close()
            wait_for_acknowledgements(node)
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


#: Longest wait at shutdown for RELIABLE subscribers to acknowledge what was published [s]. A
#: sample the transport dropped is resent only when the reader answers the writer's heartbeat
#: (Fast DDS: every 3 s by default).
ACK_TIMEOUT_S = 5.0


def wait_for_acknowledgements(node: Node, timeout_s: float = ACK_TIMEOUT_S) -> bool:
    """Before exit: let RELIABLE subscribers (the sim-mode recorder) receive all this node published.

    A process that exits takes the samples it has not delivered with it, and at the end of a
    sim run the recorder is the furthest behind (2 s runs ended with the bag missing the last
    68-159 samples). BEST_EFFORT publishers return at once. Logs, and returns False, when a
    topic stayed unacknowledged.
    """
    deadline = time.monotonic() + timeout_s
    unacked = []
    for pub in list(node.publishers):
        left = max(0.0, deadline - time.monotonic())
        if not pub.wait_for_all_acked(Duration(seconds=left)):
            unacked.append(pub.topic_name)
    if unacked:
        node.get_logger().warning(f'exiting with samples not acknowledged by every subscriber on '
                                  f'{", ".join(unacked)} after {timeout_s:g} s: a RELIABLE subscriber (the recorder?) missed them')
    return not unacked


def set_realtime_priority(priority: int) -> str | None:
    """SCHED_FIFO at ``priority`` for this process, as ros2_control's thread_priority does.

    Returns None on success, or the reason it was refused (no CAP_SYS_NICE, a container):
    the node then logs it and runs with normal scheduling. Memory is not locked
    (ros2_control's lock_memory): mlockall made every mapped page of the middleware
    resident here, 300-400 MB per node against a target of 80 MB.
    """
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError) as exc:
        return (f'SCHED_FIFO priority {priority} refused ({exc}); running with normal scheduling '
                '(grant CAP_SYS_NICE or an rtprio limit to enable it)')
    return None


def ns_to_stamp(ns: int):
    """Integer nanoseconds to builtin_interfaces/Time."""
    from builtin_interfaces.msg import Time
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def joint_position(msg, joint_name: str) -> float | None:
    """The named joint's angle in a sensor_msgs/JointState (a sole unnamed joint is accepted), or None."""
    if msg.name:
        if joint_name not in msg.name:
            return None
        index = list(msg.name).index(joint_name)
    else:
        index = 0
    return msg.position[index] if index < len(msg.position) else None


class RateLimitedLog:
    """At most one message per key and period, cheap when suppressed.

    rclpy's ``throttle_duration_sec`` inspects the calling frame on every call, suppressed
    or not: 0.6 ms a call measured here, which at 1 kHz turns one late sample into a
    cascade. This checks a monotonic clock first and only then formats and logs; the
    message is a callable so that a suppressed one costs no formatting either.
    """

    def __init__(self, logger, period_s: float = 1.0):
        """Wrap ``logger`` (a node's get_logger())."""
        self.logger = logger
        self.period_ns = int(period_s * 1e9)
        self.last_ns: dict[str, int] = {}
        self.suppressed: dict[str, int] = {}

    def _emit(self, level: str, key: str, message: Callable[[], str]) -> None:
        """Log now if this key's period has passed, else count it."""
        now = time.monotonic_ns()
        if now - self.last_ns.get(key, -self.period_ns) < self.period_ns:
            self.suppressed[key] = self.suppressed.get(key, 0) + 1
            return
        self.last_ns[key] = now
        skipped = self.suppressed.pop(key, 0)
        text = message() + (f' ({skipped} more like this since the last report)' if skipped else '')
        # One call site per severity: rclpy refuses a severity change at the same call site.
        if level == 'error':
            self.logger.error(text)
        else:
            self.logger.warning(text)

    def warn(self, key: str, message: Callable[[], str]) -> None:
        """Rate-limited warning."""
        self._emit('warning', key, message)

    def error(self, key: str, message: Callable[[], str]) -> None:
        """Rate-limited error."""
        self._emit('error', key, message)
