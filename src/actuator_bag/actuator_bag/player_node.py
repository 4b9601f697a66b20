# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``player``: publishes a bag's messages again at their recorded timing (scaled by ``rate``).

Messages are published as the recorded serialized bytes (rclpy's Publisher.publish accepts
bytes and hands them to rmw unchanged), on publishers of the recorded type imported from the
installed message packages, so a replayed message is byte-identical to the recorded one.
QoS: KEEP_LAST with a deep queue, RELIABLE by default. Timing follows the recorded log
times: message k goes out at start + (t_k - t_0) / rate on the monotonic clock.
SIGINT/SIGTERM at any moment (also during the imports: entry.py) stop it with exit 0.

The node is a ``ProcessMember`` in a process started by ``run_nodes``: ``autostart`` starts the
playing thread, which ends the run (``finished``) when the bag is played through or could not be
played (``release`` then says why in one line ``player: error: ...``, exit 1); ``halt`` stops it.
"""

from __future__ import annotations

import argparse
import math
import threading
import time
from pathlib import Path
from typing import Any, Optional, Sequence

from rclpy.node import Node

from actuator_ros.node import declare_realtime
from actuator_ros.process_member import MemberError, ProcessMember
from actuator_ros.realtime import RealtimeSettings

from .errors import BagError
from .progress import Progress
from .reading import open_bag, topic_names
from .ros_common import make_qos, message_class, run_bag_node

#: Sleep in coarse steps until this close to a message's due time, then spin [s].
_SPIN_WINDOW_S = 0.0015


def _absolute(name: str) -> str:
    """Return a topic selection entry as a fully qualified name."""
    return name if name.startswith('/') else '/' + name


class PlayerNode(Node, ProcessMember):
    """Holds one publisher per replayed topic and publishes bag messages on schedule."""

    def __init__(
        self, defaults: argparse.Namespace, settings: RealtimeSettings = RealtimeSettings()
    ) -> None:
        """Declare parameters (defaults from the command line) and validate them."""
        super().__init__('player')
        declare_realtime(self, settings)
        self.declare_parameter('bag', defaults.bag or '')
        self.declare_parameter('rate', float(defaults.rate))
        self.declare_parameter('topics', list(defaults.topics) or [''])
        self.declare_parameter('loop', bool(defaults.loop))
        self.declare_parameter('reliability', defaults.reliability)
        self.declare_parameter('queue_depth', int(defaults.queue_depth))
        self.declare_parameter('wait_for_subscribers', int(defaults.wait_for_subscribers))
        self.declare_parameter('wait_timeout', float(defaults.wait_timeout))
        self.declare_parameter('start_delay', float(defaults.start_delay))
        self.bag = Path(str(self.get_parameter('bag').value))
        self.rate = float(self.get_parameter('rate').value)
        self.topics = [t for t in (self.get_parameter('topics').value or []) if t]
        self.loop = bool(self.get_parameter('loop').value)
        self.wait_for = int(self.get_parameter('wait_for_subscribers').value)
        self.wait_timeout = float(self.get_parameter('wait_timeout').value)
        self.start_delay = float(self.get_parameter('start_delay').value)
        if not str(self.get_parameter('bag').value):
            raise BagError('no bag given (player BAG, or --ros-args -p bag:=PATH)')
        if not (math.isfinite(self.rate) and self.rate > 0):
            raise BagError(f'rate must be a finite number > 0, not {self.rate}')
        if self.wait_for < 0 or not self.wait_timeout > 0 or self.start_delay < 0:
            raise BagError(
                'wait_for_subscribers must be >= 0, wait_timeout > 0 and start_delay >= 0'
            )
        self.qos = make_qos(
            str(self.get_parameter('reliability').value),
            int(self.get_parameter('queue_depth').value),
        )
        self.publishers_: dict[int, Any] = {}
        self.counts: dict[str, int] = {}
        self.stop_requested = threading.Event()
        self.elapsed_s = 0.0
        self.played_through = False  # the bag played to its end, not stopped
        self.failure = ''  # why the bag could not be played (said once, at release)
        self._thread = threading.Thread(target=self._run, name='player', daemon=True)

    # --- ProcessMember: the playing thread ends the run ---------------------------------------
    def autostart(self) -> bool:
        """Start playing."""
        self._thread.start()
        return True

    def _run(self) -> None:
        """Play; what ends it ends the run (an error with its one line)."""
        try:
            self.play(self.stop_requested)
            self.played_through = not self.stop_requested.is_set()
        except BagError as err:
            self.failure = str(err)
        except Exception as exc:  # noqa: BLE001 - said at release, never lost with the thread
            self.failure = f'playing failed: {exc!r}'
        self.finished = True

    def halt(self) -> None:
        """Stop playing (the message being waited for is not sent)."""
        self.stop_requested.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)

    def release(self) -> None:
        """Print the summary line; a failed run says its reason instead."""
        if self.failure:
            raise MemberError(self.failure)
        per_topic = ', '.join(f'{k}={v}' for k, v in self.counts.items())
        how = 'done' if self.played_through else 'stopped'
        print(
            f'player: {how}: published {sum(self.counts.values())} messages '
            f'in {self.elapsed_s:.3f} s ({per_topic})',
            flush=True,
        )

    def play(self, stop: threading.Event) -> None:
        """Replay the bag (repeatedly with loop) until done or ``stop`` is set.

        ``elapsed_s``: the seconds spent publishing.
        """
        with open_bag(self.bag) as reader:
            conns = reader.connections
            if self.topics:
                wanted = {_absolute(t) for t in self.topics}
                missing = wanted - {c.topic for c in conns}
                if missing:
                    raise BagError(
                        f'{self.bag}: no topic {", ".join(sorted(missing))}; '
                        f'the bag has: {topic_names(conns)}'
                    )
                conns = [c for c in conns if c.topic in wanted]
            if not conns:
                raise BagError(f'{self.bag}: nothing to play (no topics)')
            playable = self._playable(conns)
            for conn, cls in playable:
                self.publishers_[conn.id] = self.create_publisher(cls, conn.topic, self.qos)
                self.counts.setdefault(conn.topic, 0)
            conns = [conn for conn, _ in playable]
            self._wait_for_subscribers(stop)
            total = sum(c.msgcount for c in conns)
            self.get_logger().info(
                f'playing {total} messages of {len(conns)} topics from {self.bag} '
                f'at rate {self.rate:g}' + (' (loop)' if self.loop else '')
            )
            started = time.monotonic()
            try:
                while not stop.is_set():
                    progress = Progress(f'player {self.bag.name}', total, unit='messages')
                    self._play_once(reader, conns, stop, progress)
                    if not self.loop:
                        break
            finally:
                self.elapsed_s = time.monotonic() - started

    def _playable(self, conns: list) -> list:
        """Return (connection, message class) of the topics whose type is installed.

        A topic of a type that is not installed is skipped with a warning (an ``ros2 bag record
        -a`` bag holds such topics, e.g. rosbag2_interfaces/msg/WriteSplitEvent), unless it was
        asked for by name; BagError when nothing is left.
        """
        playable, skipped = [], []
        for conn in conns:
            try:
                playable.append((conn, message_class(conn.msgtype)))
            except BagError as err:
                if self.topics:
                    raise BagError(f'{self.bag}: {conn.topic}: {err}') from None
                skipped.append(f'{conn.topic} [{conn.msgtype}, {conn.msgcount} messages]')
        if skipped:
            self.get_logger().warning(
                f'skipping {len(skipped)} topic(s) whose type is not installed: '
                f'{", ".join(skipped)}'
            )
        if not playable:
            raise BagError(f'{self.bag}: nothing to play: no topic has an installed type')
        return playable

    def _wait_for_subscribers(self, stop: threading.Event) -> None:
        """Block until every publisher has wait_for_subscribers matched subscriptions.

        Then wait start_delay.
        """
        deadline = time.monotonic() + self.wait_timeout
        while self.wait_for and not stop.is_set():
            if all(p.get_subscription_count() >= self.wait_for for p in self.publishers_.values()):
                break
            if time.monotonic() > deadline:
                raise BagError(
                    f'no {self.wait_for} subscriber(s) on every topic '
                    f'within {self.wait_timeout:g} s'
                )
            time.sleep(0.02)
        end = time.monotonic() + self.start_delay
        while not stop.is_set() and time.monotonic() < end:
            time.sleep(0.02)

    def _play_once(
        self, reader: Any, conns: list, stop: threading.Event, progress: Progress
    ) -> None:
        """Publish every message once on schedule."""
        start_wall: Optional[float] = None
        first_ns = 0
        done = 0
        publishers = self.publishers_
        counts = self.counts
        for conn, log_ns, raw in reader.messages(connections=conns):
            if start_wall is None:
                start_wall, first_ns = time.monotonic(), log_ns
            due = start_wall + (log_ns - first_ns) * 1e-9 / self.rate
            while True:
                if stop.is_set():
                    return
                left = due - time.monotonic()
                if left <= 0:
                    break
                if left > _SPIN_WINDOW_S:
                    time.sleep(min(left - _SPIN_WINDOW_S, 0.1))
            publishers[conn.id].publish(bytes(raw))
            counts[conn.topic] += 1
            done += 1
            if done % 500 == 0:
                progress.update(done)
        progress.update(done)


DESCRIPTION = (
    'Publish the messages of a rosbag2 (MCAP) bag again at their recorded timing. Each option '
    'sets the default of the node parameter of the same name (override with --ros-args -p '
    'name:=value).'
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the player's options to ``parser``."""
    parser.add_argument('bag', nargs='?', default='', help='bag folder (or .mcap file) to play')
    parser.add_argument(
        '--rate', type=float, default=1.0, help='time scale factor > 0 (default: %(default)s)'
    )
    parser.add_argument(
        '--topics', nargs='+', default=[], metavar='NAME', help='topics to play (default: all)'
    )
    parser.add_argument('--loop', action='store_true', help='start again at the end until stopped')
    parser.add_argument(
        '--reliability',
        choices=('reliable', 'best_effort'),
        default='reliable',
        help='publisher reliability (default: %(default)s)',
    )
    parser.add_argument(
        '--queue-depth',
        dest='queue_depth',
        type=int,
        default=1000,
        help='publisher KEEP_LAST depth (default: %(default)s)',
    )
    parser.add_argument(
        '--wait-for-subscribers',
        dest='wait_for_subscribers',
        type=int,
        default=0,
        metavar='N',
        help='before playing, wait until every topic has N subscribers (default: %(default)s)',
    )
    parser.add_argument(
        '--wait-timeout',
        dest='wait_timeout',
        type=float,
        default=30.0,
        help='longest wait for subscribers [s] (default: %(default)s)',
    )
    parser.add_argument(
        '--start-delay',
        dest='start_delay',
        type=float,
        default=0.0,
        help='pause before the first message, e.g. to let discovery settle [s] '
        '(default: %(default)s)',
    )


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``player``: its one node in a process started by ``run_nodes``."""
    return run_bag_node('player', DESCRIPTION, add_arguments, PlayerNode, argv)


if __name__ == '__main__':
    raise SystemExit(main())
