# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``recorder``: records the system's topics into a rosbag2 (MCAP) bag, losing nothing at 1 kHz.

Hot path: one raw (serialized, never deserialized) subscription per topic, BEST_EFFORT
KEEP_LAST with a deep queue (default 1000, i.e. one second at 1 kHz of backlog per topic).
A best-effort subscription matches both best-effort and reliable publishers. The callback
only stamps the message and appends it to a deque; a writer thread drains the deque into
the BagWriter (chunking, zstd, flush every second), so file I/O and compression never
block the executor. The executor defaults to rclpy's EventsExecutor, which costs far less
per message than the SingleThreadedExecutor.

Timestamps: a message's log time is its receive time on the node's ROS clock, as ros2 bag
record does, not its header.stamp: every topic gets a time (also ones without a header),
playback reproduces the timing the recorder saw, and the header.stamp stays in the message
for pairing. With use_sim_time that clock is sim time from /clock; otherwise it is system
time taken in the callback. (With ``--executor single`` the middleware's reception
timestamp is used instead, which executor queueing does not delay, and publish_time is the
publisher's source timestamp; rclpy 7.1's EventsExecutor fails with SystemError on
callbacks that take message info, so the default executor stamps in the callback.)
bag_analyze pairs samples by header.stamp and computes command latency as log time minus
header.stamp.

SIGINT/SIGTERM (at any moment, also during the imports: entry.py): stop taking new messages,
write what was received, close the bag (MCAP summary, metadata.yaml), print one summary line,
exit 0. SIGKILL: what was flushed (all but the last <= 1 s / 1 MiB) stays on disk and
``bag_repair`` recovers it. A failed write (disk full: ENOSPC, or any OSError) is noticed at
once (within 0.1 s): the recorder stops, the file is cut back to its last complete chunk (so
``bag_repair`` recovers all of it; there is no room for an index or metadata.yaml), one error
line says how many messages are on disk and how many were lost, and it exits 1.

Parameters (each declared with a description, defaults from the command line): a value of the
wrong type or a name it does not declare is refused with one line and exit 2, unless
``allow_unknown_parameters:=true``.
"""

from __future__ import annotations

import argparse
import collections
import faulthandler
import signal
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Optional, Sequence

import rclpy
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args

from .bag_format import (
    DEFAULT_CHUNK_SIZE,
    DEFAULT_FLUSH_INTERVAL_S,
    BagSummary,
    BagWriter,
    TopicSpec,
)
from .errors import BagError, BagIOError
from .msgdefs import DefinitionSource, normalize_msgtype
from actuator_ros.parameters import (
    ParameterError,
    check_unknown_parameters,
    declare_choice,
    declare_flag,
    declare_number,
    declare_text,
    declare_text_list,
)
from actuator_core.health import HealthMonitor, Level, Snapshot
from actuator_ros.diagnostics import NodeDiagnostics
from actuator_ros.runner import make_executor

from .ros_common import EXECUTORS, StopFlag, make_qos, message_class, to_bag_qos

#: The system's topics (relative names) and their types.
SYSTEM_TOPICS = {
    'joint_states': 'sensor_msgs/msg/JointState',
    'current_command': 'actuator_msgs/msg/CurrentCommand',
    'eso/estimate': 'actuator_msgs/msg/StateEstimate',
    'controller/state': 'actuator_msgs/msg/ControllerState',
    'plant/truth': 'actuator_msgs/msg/PlantTruth',
    '/clock': 'rosgraph_msgs/msg/Clock',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
}
DEFAULT_TOPICS = [
    'joint_states',
    'current_command',
    'eso/estimate',
    'controller/state',
    'plant/truth',
]


def parse_topic(entry: str) -> tuple[str, str]:
    """``name`` (a system topic) or ``name:pkg/msg/Type`` -> (name, type).

    A system topic may stand under a namespace (``/joint1/joint_states``: several joints).
    """
    name, sep, msgtype = entry.partition(':')
    name = name.strip()
    if not name:
        raise BagError(f'empty topic name in {entry!r}')
    if sep:
        return name, normalize_msgtype(msgtype.strip())
    if name in SYSTEM_TOPICS:
        return name, SYSTEM_TOPICS[name]
    for topic, system_type in SYSTEM_TOPICS.items():
        if not topic.startswith('/') and name.endswith(f'/{topic}'):
            return name, system_type
    raise BagError(f'topic {name!r} is not a system topic; give its type as {name}:pkg/msg/Type')


def default_output(now: Optional[datetime] = None) -> Path:
    """Return ``bags/<UTC timestamp>`` under the working directory.

    With a suffix if that exists already.
    """
    stamp = (now or datetime.now(timezone.utc)).strftime('%Y%m%dT%H%M%SZ')
    path = Path('bags') / stamp
    n = 1
    while path.exists():
        path = Path('bags') / f'{stamp}_{n}'
        n += 1
    return path


class BagWriterThread(threading.Thread):
    """Drains (topic, log time, publish time, data) items from a deque into a BagWriter."""

    def __init__(self, writer: BagWriter, specs: list[TopicSpec]) -> None:
        """Write into an open BagWriter; topics are registered when their first message arrives."""
        super().__init__(name='bag-writer', daemon=True)
        self.writer = writer
        self.specs = specs
        self.queue: collections.deque = collections.deque()
        self.handles: dict[int, int] = {}
        self.max_backlog = 0
        self.written = 0
        self.error: Optional[BaseException] = None
        self._stop_requested = threading.Event()

    def stop(self) -> None:
        """Ask the thread to write what is queued and end."""
        self._stop_requested.set()

    def run(self) -> None:
        """Write until stopped and the queue is empty."""
        queue = self.queue
        writer = self.writer
        try:
            while True:
                backlog = len(queue)
                if backlog > self.max_backlog:
                    self.max_backlog = backlog
                if not backlog:
                    if self._stop_requested.is_set():
                        return
                    writer.flush_if_due()
                    time.sleep(0.002)
                    continue
                for _ in range(backlog):
                    index, log_ns, pub_ns, data = queue.popleft()
                    handle = self.handles.get(index)
                    if handle is None:
                        handle = self.handles[index] = writer.add_topic(self.specs[index])
                    writer.write(handle, log_ns, data, pub_ns)
                    self.written += 1
        except BaseException as err:  # noqa: BLE001 - reported by the node on shutdown
            self.error = err


class RecorderNode(Node):
    """Subscribes raw to each topic and hands messages to the writer thread."""

    def __init__(self, defaults: argparse.Namespace, **node_options: Any) -> None:
        """Declare parameters (defaults from the command line), resolve topics, open the bag."""
        super().__init__('recorder', **node_options)
        declare_flag(
            self,
            'allow_unknown_parameters',
            False,
            'accept parameter names the recorder does not declare, with a warning, '
            'instead of refusing them',
        )
        entries = declare_text_list(
            self,
            'topics',
            list(defaults.topics) or [''],
            'topics to record: a system topic name, or name:pkg/msg/Type',
        )
        record_clock = declare_flag(
            self, 'record_clock', bool(defaults.record_clock), 'also record /clock'
        )
        record_diagnostics = declare_flag(
            self,
            'record_diagnostics',
            bool(defaults.record_diagnostics),
            'also record /diagnostics (every node of the loop reports there)',
        )
        output = declare_text(
            self,
            'output',
            defaults.output or '',
            'bag folder to create (must not exist); empty: bags/<UTC timestamp>',
        )
        depth = declare_number(
            self,
            'queue_depth',
            int(defaults.queue_depth),
            1,
            10_000_000,
            'messages',
            'subscription KEEP_LAST depth per topic',
        )
        reliability = declare_choice(
            self,
            'reliability',
            str(defaults.reliability),
            ('best_effort', 'reliable'),
            'subscription reliability; best_effort matches every publisher',
        )
        flush_interval = declare_number(
            self,
            'flush_interval',
            float(defaults.flush_interval),
            1e-3,
            3600.0,
            's',
            'longest time data stays in memory before it is written',
        )
        chunk_size = declare_number(
            self,
            'chunk_size',
            int(defaults.chunk_size),
            1024,
            1 << 30,
            'bytes',
            'MCAP chunk size before compression',
        )
        unknown = check_unknown_parameters(self)
        if unknown:
            self.get_logger().warning(
                f'ignoring parameters the recorder does not have: {", ".join(unknown)}'
            )
        entries = [e for e in entries if e]
        if record_clock and '/clock' not in entries:
            entries.append('/clock')
        if record_diagnostics and '/diagnostics' not in entries:
            entries.append('/diagnostics')
        if not entries:
            raise BagError('no topics to record')
        topics = [parse_topic(e) for e in entries]
        qos = make_qos(reliability, depth)
        path = Path(output) if output else default_output()
        self.sim_time = bool(self.get_parameter('use_sim_time').value)
        source = DefinitionSource()
        self.specs: list[TopicSpec] = []
        self._pending: list[tuple[str, str, str]] = []
        self.lost = 0
        classes = []
        for name, msgtype in topics:
            classes.append(message_class(msgtype))
            resolved = self.resolve_topic_name(name)
            self._pending.append((resolved, msgtype, source.full_text(msgtype)))
        self._source = source
        self.writer = BagWriter(
            path,
            chunk_size=chunk_size,
            flush_interval_s=flush_interval,
            custom_data={
                'recorder': 'actuator_bag recorder',
                'log_time': 'receive time on the recorder node clock'
                + (' (sim time)' if self.sim_time else ''),
                # rosbag2 stores the publisher's source timestamp; rclpy gives it only through
                # message info, which rclpy 7.1.6's EventsExecutor cannot deliver (SystemError:
                # null argument to internal routine, tested), so with the default executor it is
                # the receive time.
                'publish_time': (
                    'publisher source timestamp (message info)'
                    if defaults.executor == 'single_threaded' and not self.sim_time
                    else 'receive time (no message info with this executor or in sim time)'
                ),
            },
        )
        self.writer.open()
        self.specs = [
            TopicSpec(name=n, msgtype=t, definition=d, type_hash=source.type_hash(t))
            for n, t, d in self._pending
        ]
        self.thread = BagWriterThread(self.writer, self.specs)
        self._seen = [False] * len(self.specs)
        self.subscriptions_ = []
        rmw = rclpy.get_rmw_implementation_identifier()
        self.lost_watched = rmw not in MESSAGE_LOST_DEADLOCK_RMWS
        events = (
            SubscriptionEventCallbacks(message_lost=self._on_lost) if self.lost_watched else None
        )
        if not self.lost_watched:
            self.get_logger().info(
                f'message-lost events not watched on {rmw}: its take_event deadlocks with a '
                'sample being lost under load (ros2/rmw_fastrtps#890), which hung the recorder '
                'at stop; a loss shows as a gap in the stamps (bag_analyze)'
            )
        for index, ((resolved, _, _), cls) in enumerate(zip(self._pending, classes)):
            self.subscriptions_.append(
                self.create_subscription(
                    cls,
                    resolved,
                    self._make_callback(index, defaults.executor == 'single_threaded'),
                    qos,
                    raw=True,
                    event_callbacks=events,
                )
            )
        self.thread.start()
        self.diagnostics = NodeDiagnostics(
            self,
            HealthMonitor(
                'recorder',
                inputs={'received': 'message on the recorded topics'},
                warn_on={'lost': 'messages lost before the recorder (middleware)'},
                stale_after_s=2.0,
            ),
            self.health,
        )
        self.get_logger().info(
            f'recording {len(self.specs)} topics into {path} '
            f'({qos.reliability.name.lower()}, depth {depth}): '
            f'{", ".join(s.name for s in self.specs)}'
        )

    def health(self) -> Snapshot:
        """Report to /diagnostics: received, written, lost, the writer's backlog."""
        thread = self.thread
        backlog = len(thread.queue)
        problems = []
        if thread.error is not None:
            problems.append((Level.ERROR, f'writing failed: {thread.error}'))
        return Snapshot(
            'active',
            {'received': thread.written + backlog, 'written': thread.written, 'lost': self.lost},
            {
                'output': str(self.writer.path),
                'topics': len(self.specs),
                'backlog': backlog,
                'max_backlog': thread.max_backlog,
                'lost_watched': 'yes' if self.lost_watched else 'no (rmw_fastrtps#890)',
            },
            problems,
        )

    def _on_lost(self, info: Any) -> None:
        """Count samples the middleware reports lost before they reached the subscription."""
        self.lost += int(getattr(info, 'total_count_change', 0))

    def _offered(self, index: int) -> TopicSpec:
        """Complete the topic's spec with the publishers' offered QoS and type hash.

        Both are taken from the graph.
        """
        spec = self.specs[index]
        try:
            infos = self.get_publishers_info_by_topic(spec.name)
        except Exception:  # noqa: BLE001 - graph queries can fail during shutdown; keep the computed spec
            return spec
        qos = tuple(to_bag_qos(i.qos_profile) for i in infos)
        hashes = {
            str(i.topic_type_hash) for i in infos if str(i.topic_type_hash).startswith('RIHS01_')
        }
        if hashes and spec.type_hash not in hashes:
            self.get_logger().warning(
                f'{spec.name}: publishers report type hash {sorted(hashes)}, '
                f'the installed definition gives {spec.type_hash}; recording the installed one'
            )
        return TopicSpec(
            name=spec.name,
            msgtype=spec.msgtype,
            definition=spec.definition,
            type_hash=spec.type_hash,
            qos=qos,
        )

    def _make_callback(self, index: int, with_info: bool) -> Any:
        """Make the raw-message callback of topic ``index``: stamp and enqueue, nothing else."""
        append = self.thread.queue.append
        clock = self.get_clock()
        sim = self.sim_time
        seen = self._seen

        def first(index: int) -> None:
            seen[index] = True
            self.specs[index] = self._offered(index)

        def callback_info(data: bytes, info: dict) -> None:
            if not seen[index]:
                first(index)
            if sim:
                log_ns = pub_ns = clock.now().nanoseconds
            else:
                log_ns = info.get('received_timestamp') or time.time_ns()
                pub_ns = info.get('source_timestamp') or log_ns
            append((index, log_ns, pub_ns, data))

        def callback(data: bytes) -> None:
            if not seen[index]:
                first(index)
            log_ns = clock.now().nanoseconds if sim else time.time_ns()
            append((index, log_ns, log_ns, data))

        return callback_info if with_info else callback

    @property
    def failed(self) -> bool:
        """True once the writer thread has stopped on an error (a failed write)."""
        return self.thread.error is not None

    def finish(self) -> BagSummary:
        """Stop the subscriptions, let the writer drain, close the bag.

        Failed writing: BagError, what is on disk.
        """
        for sub in self.subscriptions_:
            self.destroy_subscription(sub)
        self.subscriptions_ = []
        self.diagnostics.destroy()
        self.thread.stop()
        self.thread.join()
        writer = self.writer
        error = self.thread.error
        if error is None:
            try:
                return writer.close()
            except BagIOError as err:
                error = err
        writer.abort()
        if not isinstance(error, BagIOError):
            raise BagError(f'writing {writer.path} failed: {error!r}')
        lost = sum(writer.counts) - writer.durable + len(self.thread.queue)
        if writer.durable == sum(writer.counts) and 'metadata.yaml' in str(error):
            rest = f'all {writer.durable} messages are in the MCAP file'
        else:
            rest = f'{writer.durable} messages are on disk, {lost} received ones were lost'
        raise BagError(
            f'{error}; recording stopped: {rest}; the bag has no metadata.yaml: '
            f'run bag_repair {writer.path}'
        )


def build_parser() -> argparse.ArgumentParser:
    """Command-line interface of the recorder.

    Each option is the default of the parameter of the same name.
    """
    parser = argparse.ArgumentParser(
        prog='recorder',
        description='Record the actuator topics into a rosbag2 (MCAP) bag. '
        'Each option sets the default of the node parameter of the same name '
        '(override with --ros-args -p name:=value). Stops on SIGINT/SIGTERM.',
    )
    parser.add_argument(
        '-o', '--output', default='', help='bag folder to create (default: bags/<UTC timestamp>)'
    )
    parser.add_argument(
        '--topics',
        nargs='+',
        default=DEFAULT_TOPICS,
        metavar='NAME[:TYPE]',
        help='topics to record; system topics need no type (default: %(default)s)',
    )
    parser.add_argument(
        '--record-clock', dest='record_clock', action='store_true', help='also record /clock'
    )
    parser.add_argument(
        '--record-diagnostics',
        dest='record_diagnostics',
        action='store_true',
        help='also record /diagnostics',
    )
    parser.add_argument(
        '--queue-depth',
        dest='queue_depth',
        type=int,
        default=1000,
        help='subscription KEEP_LAST depth per topic (default: %(default)s)',
    )
    parser.add_argument(
        '--reliability',
        choices=('best_effort', 'reliable'),
        default='best_effort',
        help='subscription reliability; best_effort matches every publisher '
        '(default: %(default)s)',
    )
    parser.add_argument(
        '--flush-interval',
        dest='flush_interval',
        type=float,
        default=DEFAULT_FLUSH_INTERVAL_S,
        help='longest time data stays in memory before it is written [s] (default: %(default)s)',
    )
    parser.add_argument(
        '--chunk-size',
        dest='chunk_size',
        type=int,
        default=DEFAULT_CHUNK_SIZE,
        help='MCAP chunk size before compression [bytes] (default: %(default)s)',
    )
    parser.add_argument(
        '--executor',
        choices=EXECUTORS,
        default='events',
        help='rclpy executor (default: %(default)s)',
    )
    return parser


#: Middlewares whose message-lost event deadlocks with a sample being lost (the AB-BA lock
#: order of take_event against on_sample_lost, fixed in ros2/rmw_fastrtps#890, not in the
#: Jazzy wheels this project pins): the recorder does not watch the event on them.
MESSAGE_LOST_DEADLOCK_RMWS = frozenset({'rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp'})


def drain(executor: Any, node: 'RecorderNode', quiet_s: float = 0.3, limit_s: float = 3.0) -> None:
    """After a stop request, take what the middleware already delivered.

    Spin until nothing new came for ``quiet_s``. A stop right after a fast run (sim time) would
    otherwise lose the messages still queued in the subscriptions; measured in CI: 208 of 2000
    samples of a 2 s lockstep run.
    """
    end = time.monotonic() + limit_s
    last, quiet_since = -1, time.monotonic()
    while rclpy.ok() and time.monotonic() < end and not node.failed:
        executor.spin_once(timeout_sec=0.05)
        received = node.thread.written + len(node.thread.queue)
        if received != last:
            last, quiet_since = received, time.monotonic()
        elif time.monotonic() - quiet_since > quiet_s:
            return


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``recorder``."""
    argv = list(sys.argv if argv is None else argv)
    args = build_parser().parse_args(remove_ros_args(argv)[1:])
    stop = StopFlag()
    stop.install()
    faulthandler.register(signal.SIGUSR1, all_threads=True)  # kill -USR1: every thread's stack
    try:
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # noqa: BLE001 - rcl's RCLError: a bad --ros-args or parameter file
        print(
            f'recorder: ROS arguments refused: {str(exc).splitlines()[0] if str(exc) else exc!r}',
            file=sys.stderr,
        )
        return 2
    node: Optional[RecorderNode] = None
    try:
        if stop.requested:
            return 0
        node = RecorderNode(args)
        executor = make_executor(args.executor)
        executor.add_node(node)
        while not stop.requested and rclpy.ok() and not node.failed:
            executor.spin_once(timeout_sec=0.1)
        if not node.failed:
            drain(executor, node)
        summary = node.finish()
        lost = f', {node.lost} reported lost by the middleware' if node.lost else ''
        print(
            f'recorder: wrote {summary.line()}; '
            f'max writer backlog {node.thread.max_backlog}{lost}',
            flush=True,
        )
        return 0
    except ParameterError as err:
        print(f'recorder: {err}', file=sys.stderr)
        return 2
    except BagError as err:
        print(f'recorder: error: {err}', file=sys.stderr)
        return 1
    finally:
        if node is not None:
            if node.writer.is_open:
                node.writer.abort()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


if __name__ == '__main__':
    raise SystemExit(main())
