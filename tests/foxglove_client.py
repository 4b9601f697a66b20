# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A small client of the Foxglove WebSocket protocol, for the live view's tests (loopback only).

It speaks what a Foxglove app does: the ``foxglove.sdk.v1`` subprotocol, serverInfo and
advertise (JSON), subscribe, binary Message Data frames (opcode 1: subscription id uint32, log
time uint64, payload), and decodes each CDR payload with the ``ros2msg`` schema the server
advertised (rosbags). It can also try what a viewer must refuse: client publishing, parameter
reads and writes, a service call.
"""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
import time
from dataclasses import dataclass, field

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from websockets.sync.client import connect

SUBPROTOCOL = 'foxglove.sdk.v1'
_DATA = struct.Struct('<BIQ')


@dataclass
class Received:
    """What a client got: per topic the (log time ns, decoded message), status messages."""

    messages: dict[str, list[tuple[int, object]]] = field(default_factory=dict)
    status: list[dict] = field(default_factory=list)
    other_binary: list[int] = field(default_factory=list)  #: opcodes of other binary frames

    def times(self, topic: str) -> list[int]:
        """Log times [ns] of a topic's messages."""
        return [t for t, _ in self.messages.get(topic, [])]


class FoxgloveClient:
    """Connects, reads the advertised channels, subscribes and decodes."""

    def __init__(self, url: str, timeout_s: float = 10.0) -> None:
        """Connect and read serverInfo and the channels advertised."""
        self.ws = connect(
            url, subprotocols=[SUBPROTOCOL], max_size=None, open_timeout=timeout_s, legacy=True
        )
        self.server_info: dict = {}
        self.channels: dict[str, dict] = {}
        self.by_sub: dict[int, dict] = {}
        self.store = get_typestore(Stores.EMPTY)
        deadline = time.monotonic() + timeout_s
        while not (self.server_info and self.channels) and time.monotonic() < deadline:
            self._handle(self.ws.recv(timeout=max(0.01, deadline - time.monotonic())), None)
        self.collect(0.3)  # channels advertised in more than one message

    def _handle(self, frame, out: Received | None) -> None:
        if isinstance(frame, str):
            msg = json.loads(frame)
            if msg['op'] == 'serverInfo':
                self.server_info = msg
            elif msg['op'] == 'advertise':
                for ch in msg['channels']:
                    self.channels[ch['topic']] = ch
                    if ch['schemaName'] not in self.store.fielddefs:
                        self.store.register(get_types_from_msg(ch['schema'], ch['schemaName']))
            elif msg['op'] == 'status' and out is not None:
                out.status.append(msg)
            return
        if frame[0] != 1:  # e.g. 3, a service call response
            if out is not None:
                out.other_binary.append(frame[0])
            return
        opcode, sub, log_ns = _DATA.unpack_from(frame)
        if out is None or sub not in self.by_sub:
            return
        ch = self.by_sub[sub]
        msg = self.store.deserialize_cdr(bytes(frame[_DATA.size :]), ch['schemaName'])
        out.messages.setdefault(ch['topic'], []).append((log_ns, msg))

    def subscribe(self, topics) -> None:
        """Subscribe to ``topics`` (advertised names)."""
        subs = []
        for topic in topics:
            sub = len(self.by_sub) + 1
            self.by_sub[sub] = self.channels[topic]
            subs.append({'id': sub, 'channelId': self.channels[topic]['id']})
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subs}))

    def collect(self, seconds: float, out: Received | None = None, until=None) -> Received:
        """Receive for ``seconds`` (or until ``until(received)`` is true)."""
        out = out or Received()
        end = time.monotonic() + seconds
        while time.monotonic() < end and not (until and until(out)):
            try:
                frame = self.ws.recv(timeout=min(0.2, max(0.01, end - time.monotonic())))
            except TimeoutError:
                continue
            self._handle(frame, out)
        return out

    def try_to_publish(self, topic: str, schema_name: str, payload: bytes) -> None:
        """Advertise a client channel and send one message on it (clientPublish)."""
        self.ws.send(
            json.dumps(
                {
                    'op': 'advertise',
                    'channels': [
                        {'id': 1, 'topic': topic, 'encoding': 'cdr', 'schemaName': schema_name}
                    ],
                }
            )
        )
        self.ws.send(struct.pack('<BI', 1, 1) + payload)

    def try_parameters(self, name: str, value) -> None:
        """Ask for every parameter, then to set one."""
        self.ws.send(json.dumps({'op': 'getParameters', 'parameterNames': [], 'id': 'get'}))
        self.ws.send(
            json.dumps(
                {'op': 'setParameters', 'parameters': [{'name': name, 'value': value}], 'id': 's'}
            )
        )

    def try_service_call(self) -> None:
        """Call service 1 (binary op 2: service id, call id, encoding length, encoding)."""
        self.ws.send(struct.pack('<BIII', 2, 1, 1, 3) + b'cdr' + b'\x00\x01\x00\x00')

    def close(self) -> None:
        """Close the connection."""
        self.ws.close()


def stuck_client(port: int, channel_ids) -> socket.socket:
    """Connect a client that subscribes, then never reads (a stuck viewer)."""
    s = socket.create_connection(('127.0.0.1', port), timeout=10)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    key = base64.b64encode(os.urandom(16)).decode()
    s.sendall(
        (
            f'GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n'
            f'Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n'
            f'Sec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n'
        ).encode()
    )
    assert b' 101 ' in s.recv(1024)
    subs = [{'id': i + 1, 'channelId': c} for i, c in enumerate(channel_ids)]
    payload = json.dumps({'op': 'subscribe', 'subscriptions': subs}).encode()
    mask = os.urandom(4)
    header = bytes([0x81]) + (
        bytes([0x80 | len(payload)])
        if len(payload) < 126
        else bytes([0x80 | 126]) + len(payload).to_bytes(2, 'big')
    )
    s.sendall(header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))
    return s
