# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Clocks: wall-clock stamps for the protocol, a monotonic clock for every age and sleep.

The samples' stamps are the system (wall) clock in real time, as ROS stamps are; a step of
that clock (NTP, an operator) must neither silence nor race the loop, so no age, timeout or
sleep is ever a difference of wall-clock readings: each receiver notes the monotonic time an
input arrived and measures ages on that clock. ``Clock`` is what the nodes hold;
``SteppedClock`` is a hand-driven one for tests (inject a wall-clock step, advance time);
``Schedule`` gives periodic deadlines on the monotonic clock with bounded catch-up (for the
joint's sample loop).
"""

from __future__ import annotations

import time


class Clock:
    """The system's clocks: ``stamp_ns`` (wall, the protocol's stamps), ``now_ns`` (monotonic)."""

    def stamp_ns(self) -> int:
        """Wall-clock time [ns]: only for stamps and for comparing with received stamps."""
        return time.time_ns()

    def now_ns(self) -> int:
        """Monotonic time [ns]: every age, timeout and deadline."""
        return time.monotonic_ns()

    def sleep_until(self, deadline_ns: int) -> None:
        """Sleep until the monotonic clock reads ``deadline_ns`` (at once if it has passed)."""
        remaining = deadline_ns - self.now_ns()
        if remaining > 0:
            time.sleep(remaining * 1e-9)


class SteppedClock(Clock):
    """A clock driven by hand: ``advance`` moves both clocks, ``step_wall`` only the wall one."""

    def __init__(self, monotonic_ns: int = 10**9, wall_offset_ns: int = 1_700_000_000 * 10**9):
        """Monotonic time and the wall clock's offset from it [ns]."""
        self.monotonic_ns = monotonic_ns
        self.wall_offset_ns = wall_offset_ns

    def stamp_ns(self) -> int:
        """Wall-clock time [ns]."""
        return self.monotonic_ns + self.wall_offset_ns

    def now_ns(self) -> int:
        """Monotonic time [ns]."""
        return self.monotonic_ns

    def advance(self, dt_ns: int) -> None:
        """Let ``dt_ns`` pass."""
        self.monotonic_ns += dt_ns

    def step_wall(self, step_ns: int) -> None:
        """Step the wall clock by ``step_ns`` (negative: backwards), as NTP may."""
        self.wall_offset_ns += step_ns

    def sleep_until(self, deadline_ns: int) -> None:
        """Advance to ``deadline_ns`` at once."""
        self.monotonic_ns = max(self.monotonic_ns, deadline_ns)


class Schedule:
    """Deadlines every ``period_ns`` on the monotonic clock; an overrun never races to catch up.

    ``next(now)`` returns the next deadline after ``now`` on the grid and how many deadlines
    were skipped: a stall of n periods costs n samples, never a burst of n samples at once.
    """

    def __init__(self, period_ns: int, start_ns: int):
        """Grid origin ``start_ns`` (monotonic)."""
        self.period_ns = period_ns
        self.deadline_ns = start_ns
        self.skipped = 0

    def next(self, now_ns: int) -> tuple[int, int]:
        """(next deadline, deadlines skipped since the last call)."""
        deadline = self.deadline_ns + self.period_ns
        skipped = 0
        if deadline <= now_ns:
            skipped = (now_ns - deadline) // self.period_ns + 1
            deadline += skipped * self.period_ns
        self.deadline_ns = deadline
        self.skipped += skipped
        return deadline, skipped
