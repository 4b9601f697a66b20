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
time taken in the callback. (With ``-p executor:=single_threaded`` the middleware's reception
timestamp is used instead, which executor queueing does not delay, and publish_time is the
publisher's source timestamp; rclpy 7.1's EventsExecutor fails with SystemError on
callbacks that take message info, so the default executor stamps in the callback.)
bag_analyze pairs samples by header.stamp and computes command latency as log time minus
header.stamp.

The process is started by ``actuator_ros.runner.run_nodes``, as every node's is, and the node
keeps its ``ProcessMember`` contract. SIGINT/SIGTERM (at any moment, also during the imports:
entry.py): take what the middleware delivered until nothing new came for ``QUIET_S``
(``settled``), write it, close the bag (MCAP summary, metadata.yaml), print one summary line,
exit 0 (``release``). SIGKILL: what was flushed (all but the last <= 1 s / 1 MiB) stays on disk and
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
import time
from pathlib import Path
from typing import Any, Optional, Sequence

import rclpy
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node

from actuator_core.health import HealthMonitor, Level, Snapshot
from actuator_ros.diagnostics import NodeDiagnostics
from actuator_ros.node import declare_realtime
from actuator_ros.parameters import (
    check_unknown_parameters,
    declare_choice,
    declare_flag,
    declare_number,
    declare_text,
    declare_text_list,
)
from actuator_ros.process_member import MemberError, ProcessMember
from actuator_ros.realtime import RealtimeSettings

from .bag_format import (
    BagSummary,
    BagWriter,
    TopicSpec,
)
from .errors import BagError, BagIOError
from .msgdefs import DefinitionSource
from .recording import (
    DESCRIPTION,
    BagWriterThread,
    add_arguments,
    default_output,
    parse_topic,
)
from .ros_common import make_qos, message_class, run_bag_node, to_bag_qos


class RecorderNode(Node, ProcessMember):
    """Subscribes raw to each topic and hands messages to the writer thread."""

    def __init__(
        self,
        defaults: argparse.Namespace,
        settings: RealtimeSettings = RealtimeSettings(),
        **node_options: Any,
    ) -> None:
        """Declare parameters (defaults from the command line), resolve topics, open the bag."""
        super().__init__('recorder', **node_options)
        executor = declare_realtime(self, settings).executor
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
                    if executor == 'single_threaded' and not self.sim_time
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
                    self._make_callback(index, executor == 'single_threaded'),
                    qos,
                    raw=True,
                    event_callbacks=events,
                )
            )
        self.thread.start()
        self._received_at_check, self._quiet_since = -1, time.monotonic()
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

    # --- ProcessMember: a failed write ends the run; at the end, take what came, then close --
    # run_nodes only reads ProcessMember.finished; here it follows the writer thread
    @property
    def finished(self) -> bool:  # type: ignore[override]
        """The run is over for the recorder once a write failed (release says why)."""
        return self.failed

    def settled(self) -> bool:
        """Whether nothing new came for QUIET_S (or a write failed).

        A stop right after a fast run (sim time) would otherwise lose the messages still queued
        in the subscriptions; measured in CI: 208 of 2000 samples of a 2 s lockstep run.
        """
        now = time.monotonic()
        received = self.thread.written + len(self.thread.queue)
        if received != self._received_at_check:
            self._received_at_check, self._quiet_since = received, now
        return self.failed or now - self._quiet_since > QUIET_S

    def release(self) -> None:
        """Close the bag and print the summary line; MemberError: what is on disk, and why."""
        try:
            summary = self.finish()
        except BagError as err:
            raise MemberError(str(err)) from None
        lost = f', {self.lost} reported lost by the middleware' if self.lost else ''
        backlog = self.thread.max_backlog
        print(f'recorder: wrote {summary.line()}; max writer backlog {backlog}{lost}', flush=True)

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


#: After the stop, the recorder has taken what was delivered once nothing new came for this long
#: [s] (ProcessMember.settled; run_nodes spins at most SETTLE_LIMIT_S for it).
QUIET_S = 0.3
#: Middlewares whose message-lost event deadlocks with a sample being lost (the AB-BA lock
#: order of take_event against on_sample_lost, fixed in ros2/rmw_fastrtps#890, not in the
#: Jazzy wheels this project pins): the recorder does not watch the event on them.
MESSAGE_LOST_DEADLOCK_RMWS = frozenset({'rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp'})


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``recorder``: its one node in a process started by ``run_nodes``."""
    return run_bag_node('recorder', DESCRIPTION, add_arguments, RecorderNode, argv)


if __name__ == '__main__':
    raise SystemExit(main())
