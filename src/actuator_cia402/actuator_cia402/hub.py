# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""An inter-process virtual CAN bus over loopback TCP: a hub and a python-can bus for its clients.

python-can's ``virtual`` interface lives in one process, so a killed master would take the
drive with it. Here the bus is a hub (a thread of the simulated drive's process, bound to
127.0.0.1) that relays every frame a client sends to every other client, as a CAN bus does;
``HubBus`` is a ``can.BusABC`` that connects to it, so canopen runs on it unchanged. A killed
client leaves the hub and the drive running, as a real bus would. The hub also sends error
frames coded as Linux SocketCAN codes them (``linux/can/error.h``), so the master's bus health
check reads the simulated and the real adapter the same way; when the hub goes away, the
client's receive fails (a vanished adapter).

Wire format, both ways: 16 bytes per frame, little endian: u32 identifier with the SocketCAN
flag bits (0x80000000 extended, 0x40000000 remote, 0x20000000 error), u8 DLC, 3 pad, 8 data.
"""

from __future__ import annotations

import queue
import select
import socket
import struct
import threading
import time
from typing import Optional, Union

import can

FRAME = struct.Struct('<IB3x8s')
CAN_EFF_FLAG = 0x80000000
CAN_RTR_FLAG = 0x40000000
CAN_ERR_FLAG = 0x20000000
CAN_EFF_MASK = 0x1FFFFFFF
#: linux/can/error.h: error class bits of the identifier, and controller status in data[1].
CAN_ERR_CRTL = 0x00000004
CAN_ERR_BUSOFF = 0x00000040
CAN_ERR_CRTL_RX_PASSIVE = 0x10
CAN_ERR_CRTL_TX_PASSIVE = 0x20
LOOPBACK = '127.0.0.1'


def encode(msg: can.Message) -> bytes:
    """One frame on the hub's wire."""
    ident = msg.arbitration_id & CAN_EFF_MASK
    ident |= CAN_EFF_FLAG if msg.is_extended_id else 0
    ident |= CAN_RTR_FLAG if msg.is_remote_frame else 0
    ident |= CAN_ERR_FLAG if msg.is_error_frame else 0
    return FRAME.pack(ident, msg.dlc, bytes(msg.data))


def decode(raw: bytes) -> can.Message:
    """Decode a frame of the hub's wire as a python-can message stamped on receipt."""
    ident, dlc, data = FRAME.unpack(raw)
    return can.Message(
        timestamp=time.time(),
        arbitration_id=ident & CAN_EFF_MASK,
        is_extended_id=bool(ident & CAN_EFF_FLAG),
        is_remote_frame=bool(ident & CAN_RTR_FLAG),
        is_error_frame=bool(ident & CAN_ERR_FLAG),
        dlc=dlc,
        data=data[:dlc],
    )


def error_frame(kind: str) -> can.Message:
    """Return an error frame as SocketCAN reports it: 'bus_off' or 'error_passive'."""
    if kind == 'bus_off':
        return can.Message(arbitration_id=CAN_ERR_BUSOFF, is_error_frame=True, dlc=8)
    if kind == 'error_passive':
        data = bytes([0, CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 0, 0, 0])
        return can.Message(arbitration_id=CAN_ERR_CRTL, is_error_frame=True, dlc=8, data=data)
    raise ValueError(f'error frame kind must be bus_off or error_passive, got {kind!r}')


def bus_error(msg: can.Message) -> Optional[str]:
    """Tell what an error frame says about this node's controller, or None when it is harmless."""
    if not msg.is_error_frame:
        return None
    if msg.arbitration_id & CAN_ERR_BUSOFF:
        return 'CAN controller bus-off'
    if msg.arbitration_id & CAN_ERR_CRTL and len(msg.data) > 1:
        if msg.data[1] & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE):
            return 'CAN controller error-passive'
    return None


class Hub:
    """The bus: relays each client's frames to every other client (a thread; 127.0.0.1 only)."""

    def __init__(self, port: int = 0):
        """Listen on 127.0.0.1:``port`` (0: any free port, see ``address``)."""
        self.server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind((LOOPBACK, port))
        self.server.listen(16)
        self.clients: dict[socket.socket, bytearray] = {}
        self.lock = threading.Lock()
        self.frames = 0
        self.dlc_counts = [0] * 9  # relayed frames by data length (bus load)
        self.local: list['LocalHubBus'] = []  # clients in the hub's own process
        self._send_lock = threading.Lock()  # one frame at a time on each connection
        self._stop = False
        self._thread = threading.Thread(target=self._run, name='can-hub', daemon=True)

    @property
    def address(self) -> str:
        """'127.0.0.1:port', the channel of its HubBus clients."""
        return f'{LOOPBACK}:{self.server.getsockname()[1]}'

    def start(self) -> 'Hub':
        """Start relaying."""
        self._thread.start()
        return self

    def stop(self) -> None:
        """Close every connection and the listening socket."""
        self._stop = True
        self._thread.join(1.0)
        with self.lock:
            for client in list(self.clients):
                client.close()
            self.clients.clear()
        self.server.close()

    def broadcast(self, msg: can.Message) -> None:
        """Send a frame of the hub itself (an error frame) to every client."""
        self._relay(encode(msg), None)

    def attach(self, **kwargs) -> 'LocalHubBus':
        """Return a bus for a client in this process (the simulated drive): no socket between."""
        bus = LocalHubBus(self, **kwargs)
        with self.lock:
            self.local.append(bus)
        return bus

    def _relay(self, raw: bytes, source: Union[socket.socket, 'LocalHubBus', None]) -> None:
        """Send ``raw`` to every client but ``source``; drop a client that cannot take it."""
        for i in range(4, len(raw), FRAME.size):
            self.dlc_counts[min(8, raw[i])] += 1
        self.frames += len(raw) // FRAME.size
        with self.lock:
            targets = [c for c in self.clients if c is not source]
            local = [b for b in self.local if b is not source]
        for bus in local:
            for i in range(0, len(raw), FRAME.size):
                bus.queue.put(raw[i : i + FRAME.size])
        with self._send_lock:
            for client in targets:
                try:
                    client.sendall(raw)
                except OSError:
                    self._drop(client)

    def _drop(self, client: socket.socket) -> None:
        """Forget a client that left."""
        with self.lock:
            self.clients.pop(client, None)
        client.close()

    def _run(self) -> None:
        """Accept clients and relay whole frames until stopped."""
        while not self._stop:
            with self.lock:
                sockets = [self.server, *self.clients]
            try:
                readable, _, _ = select.select(sockets, [], [], 0.05)
            except (OSError, ValueError):
                continue  # a client closed between the listing and the select
            for sock in readable:
                if sock is self.server:
                    client, _ = self.server.accept()
                    client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    with self.lock:
                        self.clients[client] = bytearray()
                    continue
                try:
                    chunk = sock.recv(4096)
                except OSError:
                    chunk = b''
                if not chunk:
                    self._drop(sock)
                    continue
                buffer = self.clients.get(sock)
                if buffer is None:
                    continue
                buffer += chunk
                whole = len(buffer) - len(buffer) % FRAME.size
                if whole:
                    data = bytes(buffer[:whole])
                    del buffer[:whole]
                    self._relay(data, sock)


class HubBus(can.BusABC):
    """A python-can bus on the hub at ``channel`` = '127.0.0.1:port'."""

    def __init__(self, channel: str, connect_timeout_s: float = 2.0, **kwargs):
        """Connect to the hub; OSError when nothing listens there."""
        host, _, port = channel.rpartition(':')
        if host != LOOPBACK:
            raise ValueError(
                f'the CAN hub is loopback only: channel must be 127.0.0.1:port, got {channel!r}'
            )
        deadline = time.monotonic() + connect_timeout_s
        while True:  # nothing listens yet: retry until the deadline
            try:
                self.sock = socket.create_connection((host, int(port)), timeout=1.0)
                break
            except ConnectionRefusedError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock.settimeout(None)
        self.channel_info = f'CAN hub {channel}'
        self.hub_address = channel
        self._buffer = bytearray()
        self._send_lock = threading.Lock()
        self._closed = False
        super().__init__(channel=channel, **kwargs)

    def send(self, msg: can.Message, timeout: Optional[float] = None) -> None:
        """Put one frame on the bus; CanOperationError when the hub is gone."""
        try:
            with self._send_lock:
                self.sock.sendall(encode(msg))
        except OSError as exc:
            raise can.CanOperationError(
                f'CAN adapter gone: hub {self.hub_address} ({exc})'
            ) from None

    def _recv_internal(self, timeout: Optional[float]):
        """Next frame within ``timeout``; CanOperationError when the hub closed the connection."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while len(self._buffer) < FRAME.size:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            try:
                readable, _, _ = select.select([self.sock], [], [], left)
            except (OSError, ValueError):
                readable = None
            if readable is None or self._closed:
                raise can.CanOperationError(f'CAN adapter closed: hub {self.hub_address}')
            if not readable:
                return None, False
            try:
                chunk = self.sock.recv(4096)
            except OSError:
                chunk = b''
            if not chunk:
                raise can.CanOperationError(
                    f'CAN adapter vanished: hub {self.hub_address} closed the connection'
                )
            self._buffer += chunk
        raw = bytes(self._buffer[: FRAME.size])
        del self._buffer[: FRAME.size]
        return decode(raw), False

    def shutdown(self) -> None:
        """Leave the bus."""
        self._closed = True
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.sock.close()
        super().shutdown()


class LocalHubBus(can.BusABC):
    """A python-can bus on a hub of this process (``Hub.attach``)."""

    def __init__(self, hub: Hub, **kwargs):
        """Join ``hub`` directly."""
        self.hub = hub
        self.queue: queue.SimpleQueue = queue.SimpleQueue()
        self.channel_info = f'CAN hub {hub.address} (in process)'
        super().__init__(channel=hub.address, **kwargs)

    def send(self, msg: can.Message, timeout: Optional[float] = None) -> None:
        """Put one frame on the bus."""
        self.hub._relay(encode(msg), self)

    def _recv_internal(self, timeout: Optional[float]):
        """Next frame within ``timeout``."""
        try:
            return decode(self.queue.get(timeout=timeout)), False
        except queue.Empty:
            return None, False

    def shutdown(self) -> None:
        """Leave the hub."""
        with self.hub.lock:
            if self in self.hub.local:
                self.hub.local.remove(self)
        super().shutdown()
