# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The live view's logic without ROS: the accounting of slow clients.

Decimation per topic is ``actuator_core.decimation.Decimator``.

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
