# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Decimation of a diagnostic stream on a time grid (the live view's topics, controller/state).

``Decimator`` admits at most ``rate_hz`` messages a second, on a grid: a 1 kHz stream at 100 Hz
passes every tenth message, not bursts; after a gap, or at a time before the grid's last point
(a restarted clock), the grid restarts at the next message. Rate
0 admits every message. ``admit(now_ns, force=True)`` admits a message off the grid (a status
change that must not be decimated away) without moving the grid.
"""

from __future__ import annotations


class Decimator:
    """At most ``rate_hz`` admitted messages per second on a fixed grid (0: admit all)."""

    def __init__(self, rate_hz: float) -> None:
        """Period 1/rate_hz; the first message is always admitted."""
        if not rate_hz >= 0:
            raise ValueError(f'rate_hz must be >= 0, not {rate_hz}')
        self.period_ns = int(round(1e9 / rate_hz)) if rate_hz > 0 else 0
        self.next_ns: int | None = None
        self.admitted = self.skipped = 0

    def admit(self, now_ns: int, force: bool = False) -> bool:
        """Tell whether the message at ``now_ns`` is sent (``force``: yes, grid unchanged)."""
        if self.period_ns == 0 or (force and self.next_ns is not None):
            self.admitted += 1
            return True
        if self.next_ns is None or now_ns < self.next_ns - self.period_ns:
            self.next_ns = now_ns + self.period_ns  # the first message, or the clock stepped back
        elif now_ns < self.next_ns:
            self.skipped += 1
            return False
        else:  # on the grid while messages keep up; after a gap the grid restarts here
            after = self.next_ns + self.period_ns
            self.next_ns = after if after > now_ns else now_ns + self.period_ns
        self.admitted += 1
        return True
