# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The live view's logic without ROS: per-topic decimation and the accounting of slow clients.

``Decimator`` passes at most ``rate_hz`` messages a second of a topic, on a grid (a 1 kHz topic
at 100 Hz passes every tenth message, not bursts), and every message at rate 0 (full rate).

Slow clients: the Foxglove SDK keeps one bounded outbox per client (``message_backlog_size``)
and drops that client's oldest data message when it is full, so a stuck client costs the
publishers and the other clients nothing. The SDK does not count its drops for the caller; it
logs that an outbox filled, and how many it dropped since its last warning. ``OutboxWatch``, a
logging handler on that logger, counts both per client: ``full_events`` is exact, ``dropped``
a lower bound (what the SDK has reported so far).
"""

from __future__ import annotations

import logging
import re
import threading

#: The SDK's logger of the lossy per-client send path.
SEND_LOSSY_LOGGER = 'foxglove.websocket.connected_client.send_lossy'
_FULL = re.compile(r'outbox for client (\S+) full')
_DROPPED = re.compile(r'client (\S+?)[:,]?\s.*?(\d+) dropped since last warning')


class Decimator:
    """At most ``rate_hz`` admitted messages per second on a fixed grid (0: admit all)."""

    def __init__(self, rate_hz: float) -> None:
        """Period 1/rate_hz; the first message is always admitted."""
        if rate_hz < 0:
            raise ValueError(f'rate_hz must be >= 0, not {rate_hz}')
        self.period_ns = int(round(1e9 / rate_hz)) if rate_hz > 0 else 0
        self.next_ns: int | None = None
        self.admitted = self.skipped = 0

    def admit(self, now_ns: int) -> bool:
        """Tell whether the message received at ``now_ns`` is sent."""
        if self.period_ns == 0:
            self.admitted += 1
            return True
        if self.next_ns is not None and now_ns < self.next_ns:
            self.skipped += 1
            return False
        # On the grid while messages keep up; after a gap the grid restarts at this message.
        after = None if self.next_ns is None else self.next_ns + self.period_ns
        self.next_ns = after if after is not None and after > now_ns else now_ns + self.period_ns
        self.admitted += 1
        return True


class OutboxWatch(logging.Handler):
    """Counts, per client, the SDK's reports of a full outbox and of dropped messages."""

    def __init__(self) -> None:
        """Nothing counted yet."""
        super().__init__(level=logging.DEBUG)
        self._lock_counts = threading.Lock()
        self.full_events: dict[str, int] = {}
        self.dropped: dict[str, int] = {}

    def emit(self, record: logging.LogRecord) -> None:
        """Count one SDK log line (called from the SDK's threads)."""
        text = record.getMessage()
        with self._lock_counts:
            if m := _DROPPED.search(text):
                self.dropped[m.group(1)] = self.dropped.get(m.group(1), 0) + int(m.group(2))
            elif m := _FULL.search(text):
                self.full_events[m.group(1)] = self.full_events.get(m.group(1), 0) + 1

    def totals(self) -> tuple[int, int]:
        """(outbox-full events, messages reported dropped) over every client."""
        with self._lock_counts:
            return sum(self.full_events.values()), sum(self.dropped.values())
