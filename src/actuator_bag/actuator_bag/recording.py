# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What the recorder records and how (ROS-free): its topics, its options, its writer thread.

``recorder_node`` is the node around these; the live view shows the same topics.
"""

from __future__ import annotations

import argparse
import collections
import threading
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Optional

from .bag_format import DEFAULT_CHUNK_SIZE, DEFAULT_FLUSH_INTERVAL_S, BagWriter, TopicSpec
from .errors import BagError
from .msgdefs import normalize_msgtype

#: The system's topics (relative names) and their types.
SYSTEM_TOPICS = {
    'joint_states': 'sensor_msgs/msg/JointState',
    'current_command': 'actuator_msgs/msg/CurrentCommand',
    'eso/estimate': 'actuator_msgs/msg/StateEstimate',
    'controller/state': 'actuator_msgs/msg/ControllerState',
    'plant/truth': 'actuator_msgs/msg/PlantTruth',
    'controller/goal_events': 'actuator_msgs/msg/GoalEvent',
    '/clock': 'rosgraph_msgs/msg/Clock',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
}
DEFAULT_TOPICS = [
    'joint_states',
    'current_command',
    'eso/estimate',
    'controller/state',
    'plant/truth',
    'controller/goal_events',
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


DESCRIPTION = (
    'Record the actuator topics into a rosbag2 (MCAP) bag. Each option sets the default of the '
    'node parameter of the same name (override with --ros-args -p name:=value). Stops on '
    'SIGINT/SIGTERM.'
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the recorder's options to ``parser``."""
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
