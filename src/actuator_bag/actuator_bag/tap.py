# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""In-process recording: a loop container records what its own nodes publish.

``InProcessRecording.hook`` goes into actuator_ros.publisher_hooks before the container builds
its nodes; each publisher on a recorded topic comes back as a ``RecordedPublisher``, which
publishes as before and hands the same bytes to a ``FrameSpool`` (actuator_bag.spool), whose
writer process writes the bag. It counts as one subscriber more, as the recorder's
subscription would (the joint waits for it; controller/state and plant/truth are filled when
somebody listens).

What it keeps and what it does not, against the recorder process: the same topics, types,
definitions, offered QoS and every message the nodes of this process published (none is lost:
a full pipe holds the loop up); the log time is the publish time on the process's sim clock
(the newest /clock it published) instead of the receive time on the recorder's. It does not
see what other processes publish (a second publisher on a topic, or a node outside the
container): those the recorder process records. Sim time only (actuator_bringup.composition
refuses a real-time run, and a node in real time stops the recording with one line): in real
time a full pipe would hold up a loop that has a deadline.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Optional, Sequence

from rclpy.lifecycle import LifecyclePublisher
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock

from actuator_core.timing import stamp_to_ns
from actuator_ros.wire_io import codec

from .recording import DEFAULT_TOPICS, parse_topic
from .ros_common import to_bag_qos
from .spool import FrameSpool, SpoolError, grow_pipe

#: What a container records in-process unless told otherwise: the recorder's default topics and
#: /diagnostics, as graph.closed_loop has the recorder process record.
IN_PROCESS_TOPICS = (*DEFAULT_TOPICS, '/diagnostics')
CLOCK_TOPIC = '/clock'
#: Seconds the writer process may take to write what is queued after the loop has ended.
WRITER_EXIT_TIMEOUT_S = 120.0


class RecordedPublisher:
    """rclpy's publisher, whose every sent message also goes to the recording."""

    __slots__ = ('inner', '_recording', '_index', '_lifecycle')

    def __init__(self, inner: Any, recording: InProcessRecording, index: Optional[int]) -> None:
        """Wrap ``inner``; ``index``: the topic's in the bag (None: /clock, followed only)."""
        self.inner = inner
        self._recording = recording
        self._index = index
        self._lifecycle = isinstance(inner, LifecyclePublisher)

    def publish(self, msg: Any) -> None:
        """Publish, then record what went out (an inactive lifecycle publisher sends nothing)."""
        inner = self.inner
        inner.publish(msg)
        if self._lifecycle and not inner.is_activated:
            return
        self._recording.add(self._index, msg)

    def get_subscription_count(self) -> int:
        """Return the matched subscriptions, and one for the recording."""
        return self.inner.get_subscription_count() + (self._index is not None)

    def __getattr__(self, name: str) -> Any:
        """Everything else is rclpy's publisher's."""
        return getattr(self.inner, name)


class InProcessRecording:
    """The bag of one container: a writer process, and the publishers that feed it."""

    def __init__(self, output: Path, topics: Sequence[str] = IN_PROCESS_TOPICS) -> None:
        """Start the writer process for the bag folder ``output`` (which must not exist)."""
        self.output = Path(output)
        self.topics = [parse_topic(t) for t in topics]
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'actuator_bag.spool', '--output', str(self.output)],
            stdin=subprocess.PIPE,
        )
        assert self.process.stdin is not None  # stdin=PIPE
        fd = self.process.stdin.fileno()
        grow_pipe(fd)
        self.spool = FrameSpool(fd)
        self.indices: dict[str, int] = {}  # resolved topic name -> index in the bag
        self.clock_index = -1  # /clock's index when it is recorded
        self.sim = False  # a /clock publisher in this process: log times on that clock
        self.now_ns = 0
        self.decode_clock = codec(Clock).decode  # the joint encodes /clock with the same codec
        self.error: Optional[str] = None
        self.not_recorded = 0

    def hook(self, node: Any, publisher: Any, msg_type: type) -> Any:
        """actuator_ros.publisher_hooks: wrap a publisher on a recorded topic (and /clock).

        A node in real time (its ``mode`` parameter) stops the recording at once, with one
        line: a full pipe would hold up its loop.
        """
        name = publisher.topic_name
        if self.error is None and node.has_parameter('mode'):
            mode = node.get_parameter('mode').value
            if mode != 'sim':
                self._fail(
                    f'it is for sim time, and {node.get_fully_qualified_name()} runs in {mode} '
                    'mode (a full pipe would hold up its loop): nothing of this run is recorded; '
                    'record a real-time run with the recorder process'
                )
        if self.error is not None:
            return publisher
        for entry, msgtype in self.topics:
            if node.resolve_topic_name(entry) == name:
                index = self.indices.get(name)
                if index is None:
                    index = self.indices[name] = len(self.indices)
                    self.spool.add_topic(index, name, msgtype, [to_bag_qos(publisher.qos_profile)])
                if name == CLOCK_TOPIC:
                    self.sim, self.clock_index = True, index
                return RecordedPublisher(publisher, self, index)
        if name == CLOCK_TOPIC:
            self.sim = True
            return RecordedPublisher(publisher, self, None)
        return publisher

    def add(self, index: Optional[int], msg: Any) -> None:
        """Record one published message of topic ``index`` (None: /clock, time only)."""
        data = msg if isinstance(msg, (bytes, bytearray)) else serialize_message(msg)
        if len(data) % 4:  # as Fast DDS delivers it to a recorder: a bag is the same either way
            data = bytes(data) + bytes(-len(data) % 4)
        if index is None or index == self.clock_index:
            self.now_ns = stamp_to_ns(self.decode_clock(bytes(data)).clock)  # (bytes: no copy)
            if index is None:
                return
        if self.error is not None:
            self.not_recorded += 1
            return
        try:
            self.spool.add(index, self.now_ns if self.sim else time.time_ns(), data)
        except SpoolError as err:
            self._fail(str(err))

    def _fail(self, why: str) -> None:
        """Stop recording, say so once; the loop runs on (its process exits 1 at the end)."""
        self.error = why
        print(f'loop_container: in-process recording stopped: {why}', file=sys.stderr, flush=True)

    def close(self) -> bool:
        """Hand over the rest, let the writer close the bag; False (and one line) on a failure."""
        if self.error is None:
            try:
                self.spool.flush()
            except SpoolError as err:
                self._fail(str(err))
        assert self.process.stdin is not None  # stdin=PIPE
        try:
            self.process.stdin.close()
        except OSError:
            pass
        try:
            code = self.process.wait(WRITER_EXIT_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            code = self.process.wait()
            print(
                f'loop_container: the bag writer took over {WRITER_EXIT_TIMEOUT_S:g} s to '
                f'finish and was killed: run bag_repair {self.output}',
                file=sys.stderr,
                flush=True,
            )
        if self.error is not None and self.not_recorded:
            print(
                f'loop_container: {self.not_recorded} messages published after the recording '
                'stopped are not in the bag',
                file=sys.stderr,
                flush=True,
            )
        return code == 0 and self.error is None
