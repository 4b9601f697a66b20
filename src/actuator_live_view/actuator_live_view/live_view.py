# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``live_view``: the running loop in Foxglove, over the Foxglove WebSocket protocol.

The server is foxglove-sdk's.

    ros2 run actuator_live_view live_view [--ros-args -p rate_hz:=100 -p port:=8765 ...]
    ros2 launch actuator_bringup closed_loop.launch.py live_view:=true
    bringup --live-view

Then in the Foxglove app: Open connection -> Foxglove WebSocket -> ws://127.0.0.1:8765, and
import the layout share/actuator_live_view/foxglove/closed_loop_layout.json
(docs/how-to/live-view.md).

Each topic is subscribed raw (rclpy ``raw=True``: the serialized CDR bytes, never decoded) and
forwarded as a ``cdr`` channel whose ``ros2msg`` schema is the full definition text the recorder
stores (actuator_bag.msgdefs), decimated per topic to at most ``rate_hz`` (default 100 Hz for
plots; 0, or a topic in ``full_rate_topics``, sends every message); /diagnostics is served too.

A viewer, never a way in: the server listens on 127.0.0.1 unless ``host`` names another
address, advertises no capability (no client publishing, services, parameters or assets: the
SDK answers such requests with an error status), and the node has no publisher but its own
/diagnostics. Subscriptions are BEST_EFFORT with a short queue, so the loop's publishers never
wait for the viewer; each client has a bounded outbox (``client_queue`` messages) whose oldest
data the SDK drops when the client is slow, counted (live_core.OutboxWatch) and reported on
/diagnostics.
"""

from __future__ import annotations

import logging
import time

import foxglove
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from actuator_bag.msgdefs import DefinitionSource
from actuator_bag.recording import DEFAULT_TOPICS as RECORDED_TOPICS
from actuator_bag.recording import parse_topic
from actuator_core.decimation import Decimator
from actuator_core.health import HealthMonitor, Level, Snapshot
from actuator_live_view.live_core import SEND_LOSSY_LOGGER, OutboxWatch
from actuator_ros.diagnostics import NodeDiagnostics
from actuator_ros.node import declare_realtime
from actuator_ros.parameters import (
    ParameterError,
    declare_number,
    declare_text,
    declare_text_list,
)
from actuator_ros.process_member import ProcessMember
from actuator_ros.runner import run_node

NODE_NAME = 'live_view'
#: What the layout shows: the topics the recorder records, and every node's health.
DEFAULT_TOPICS = [*RECORDED_TOPICS, '/diagnostics']
#: Never waits for the viewer; a short queue, the newest kept.
VIEW_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.BEST_EFFORT
)


class _Subscribers(foxglove.websocket.ServerListener):
    """Tracks which client subscribed to which channel (for the count of viewers)."""

    def __init__(self) -> None:
        self.by_client: dict[int, set[int]] = {}
        self.subscribes = 0

    def on_subscribe(self, client, channel) -> None:
        self.subscribes += 1
        self.by_client.setdefault(client.id, set()).add(channel.id)

    def on_unsubscribe(self, client, channel) -> None:
        channels = self.by_client.get(client.id, set())
        channels.discard(channel.id)
        if not channels:
            self.by_client.pop(client.id, None)


class LiveViewNode(Node, ProcessMember):
    """Forwards the loop's serialized messages to Foxglove clients, decimated per topic."""

    def __init__(self, settings=None) -> None:
        """Declare the parameters, start the server; one channel and subscription per topic."""
        super().__init__(NODE_NAME)
        if settings is not None:
            declare_realtime(self, settings)
        host = declare_text(
            self,
            'host',
            '127.0.0.1',
            'address the WebSocket server listens on (127.0.0.1: this machine only; name '
            'another address to let other hosts watch)',
        )
        port = declare_number(
            self, 'port', 8765, 0, 65535, '', 'WebSocket port (0: any free port, logged)'
        )
        entries = declare_text_list(
            self,
            'topics',
            DEFAULT_TOPICS,
            'topics to serve: a system topic name, or name:pkg/msg/Type',
        )
        self.rate_hz = declare_number(
            self,
            'rate_hz',
            100.0,
            0.0,
            1.0e5,
            'Hz',
            'largest rate per topic sent to clients (0: every message)',
        )
        full_rate = {
            self.resolve_topic_name(t)
            for t in declare_text_list(
                self, 'full_rate_topics', [''], 'topics sent at full rate whatever rate_hz says'
            )
            if t
        }
        backlog = declare_number(
            self,
            'client_queue',
            1024,
            16,
            1_000_000,
            'messages',
            "per-client outbox; a slow client's oldest messages are dropped beyond it",
        )
        try:
            topics = [parse_topic(e) for e in entries if e]
        except Exception as exc:  # noqa: BLE001 - BagError, DefinitionError: one line
            raise ParameterError(f"parameter 'topics' refused: {exc}") from None
        if not topics:
            raise ParameterError("parameter 'topics' refused: no topic to serve")
        self.watch = OutboxWatch()
        sdk_log = logging.getLogger(SEND_LOSSY_LOGGER)
        sdk_log.addHandler(self.watch)
        sdk_log.setLevel(logging.INFO)
        logging.basicConfig(level=logging.WARNING)  # the SDK's warnings and errors on stderr
        foxglove.set_log_level('INFO')  # its send path's INFO lines reach the watch
        source = DefinitionSource()
        self.received = self.forwarded = 0
        self.decimators: dict[str, Decimator] = {}
        self.subs = []
        for name, msgtype in topics:
            resolved = self.resolve_topic_name(name)
            channel = foxglove.Channel(
                resolved,
                message_encoding='cdr',
                schema=foxglove.Schema(
                    name=msgtype, encoding='ros2msg', data=source.full_text(msgtype).encode()
                ),
            )
            decimator = Decimator(0.0 if resolved in full_rate else self.rate_hz)
            self.decimators[resolved] = decimator
            cls = _message_class(msgtype)
            self.subs.append(
                self.create_subscription(
                    cls, resolved, self._forwarder(channel, decimator), VIEW_QOS, raw=True
                )
            )
        # The channels exist before the server: a client's first advertise lists them all.
        self.listener = _Subscribers()
        try:
            self.server = foxglove.start_server(
                name='actuator live view',
                host=host,
                port=int(port),
                capabilities=[],
                server_listener=self.listener,
                message_backlog_size=int(backlog),
            )
        except RuntimeError as exc:  # FoxgloveError: the address is taken or not this host's
            raise ParameterError(
                f'cannot listen on {host}:{port} ({str(exc).removeprefix("FoxgloveError: ")}); '
                'another live view? choose another with -p port:=N'
            ) from None
        self.diagnostics = NodeDiagnostics(
            self,
            HealthMonitor(NODE_NAME, warn_on={'outbox_full': 'client outboxes full (drops)'}),
            self.health,
        )
        self.get_logger().info(
            f'serving {len(topics)} topics on ws://{host}:{self.server.port} at '
            f'{"full rate" if not self.rate_hz else f"<= {self.rate_hz:g} Hz per topic"}'
            f'{f" ({len(full_rate)} at full rate)" if full_rate else ""}: '
            f'{", ".join(self.decimators)}'
        )

    def _forwarder(self, channel, decimator: Decimator):
        """Make the raw callback of one topic: decimate, then hand the bytes to the SDK."""
        log, admit = channel.log, decimator.admit

        def forward(data: bytes) -> None:
            self.received += 1
            now = time.time_ns()
            if admit(now):
                log(data, log_time=now)
                self.forwarded += 1

        return forward

    def health(self) -> Snapshot:
        """Report to /diagnostics: clients, messages in and out, outbox drops."""
        full, dropped = self.watch.totals()
        return Snapshot(
            'active',
            {
                'received': self.received,
                'forwarded': self.forwarded,
                'outbox_full': full,
                'dropped_reported': dropped,
            },
            {'port': self.server.port, 'clients': len(self.listener.by_client)},
            [(Level.WARN, f'{dropped} messages dropped for slow clients')] if dropped else [],
        )

    def release(self) -> None:
        """Stop the server (ProcessMember: at exit)."""
        self.diagnostics.destroy()
        self.server.stop()


def _message_class(msgtype: str):
    """Return the installed class of ``msgtype`` (ParameterError when it is not)."""
    from actuator_bag.errors import BagError
    from actuator_bag.ros_common import message_class

    try:
        return message_class(msgtype)
    except BagError as exc:
        raise ParameterError(f"parameter 'topics' refused: {exc}") from None


def main(argv=None) -> int:
    """Entry point of ``ros2 run actuator_live_view live_view``."""
    return run_node(
        'live_view',
        'Serve the running loop to Foxglove (WebSocket, foxglove-sdk), decimated per topic.',
        LiveViewNode,
        NODE_NAME,
        argv,
    )


if __name__ == '__main__':
    raise SystemExit(main())
