# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Clocks: stamp time for the protocol, monotonic time for every age and sleep.

Two kinds of time, named so everywhere:

- **stamp time** [ns]: what a sample's ``header.stamp`` says, the system (wall) clock's domain as
  ROS stamps are. The joint anchors its sample grid on the wall clock once, at start, and then
  counts periods on the monotonic clock; a receiver compares stamps with ``StampClock.now_ns``,
  which is the same domain kept on the monotonic clock, so a step of the wall clock (NTP,
  chrony, ``date -s``, a PTP relock) moves neither the stamps nor the receivers' judgement of
  them. A receiver re-anchors its ``StampClock`` only when it adopts a new time base (a
  restarted joint whose stamps follow the stepped wall clock).
- **monotonic time** [ns]: every age, timeout, deadline and sleep (``Clock.now_ns``).

``Clock.wall_ns`` is read only to anchor. ``SteppedClock`` is a hand-driven clock for tests;
``Schedule`` gives periodic deadlines on the monotonic clock with bounded catch-up (the joint's
sample loop). ``ACTUATOR_WALL_CLOCK_STEPS`` injects wall-clock steps into every ``Clock`` of a
process (``MONO_S:STEP_S,...``: at monotonic time MONO_S the wall clock steps by STEP_S), so a
test can step the clock of every node of a running loop at one instant.
"""

from __future__ import annotations

import os
import time

#: Fault injection: wall-clock steps every Clock of this process applies (see the module doc).
STEPS_ENV = 'ACTUATOR_WALL_CLOCK_STEPS'


def _injected_steps() -> tuple[tuple[int, int], ...]:
    """Return (monotonic ns, step ns) of the steps ACTUATOR_WALL_CLOCK_STEPS asks for."""
    text = os.environ.get(STEPS_ENV, '').strip()
    steps = []
    for item in filter(None, (part.strip() for part in text.split(','))):
        at_s, _, step_s = item.partition(':')
        steps.append((int(float(at_s) * 1e9), int(float(step_s) * 1e9)))
    return tuple(sorted(steps))


class Clock:
    """The system's clocks: ``wall_ns`` (may step), ``now_ns`` (monotonic)."""

    def __init__(self) -> None:
        """Read the injected wall-clock steps (none in normal use)."""
        self.steps = _injected_steps()

    def wall_ns(self) -> int:
        """Return the system's wall-clock time [ns]: read only to anchor stamp time."""
        wall = time.time_ns()
        if self.steps:
            now = time.monotonic_ns()
            wall += sum(step for at, step in self.steps if at <= now)
        return wall

    def now_ns(self) -> int:
        """Return monotonic time [ns]: every age, timeout and deadline."""
        return time.monotonic_ns()

    def sleep_until(self, deadline_ns: int) -> None:
        """Sleep until the monotonic clock reads ``deadline_ns`` (at once if it has passed)."""
        remaining = deadline_ns - self.now_ns()
        if remaining > 0:
            time.sleep(remaining * 1e-9)


class StampClock:
    """Stamp time kept on the monotonic clock: a step of the wall clock does not move it."""

    def __init__(self, clock: Clock) -> None:
        """Anchor on ``clock``'s wall clock now."""
        self.clock = clock
        self.offset_ns = 0
        self.anchor()

    def anchor(self) -> None:
        """Take the wall clock's offset from the monotonic clock now (start, configure)."""
        self.offset_ns = self.clock.wall_ns() - self.clock.now_ns()

    def adopt(self, stamp_ns: int, monotonic_ns: int) -> None:
        """Make ``stamp_ns`` the stamp time of monotonic ``monotonic_ns`` (a new time base)."""
        self.offset_ns = stamp_ns - monotonic_ns

    def now_ns(self) -> int:
        """Return stamp time now [ns]."""
        return self.clock.now_ns() + self.offset_ns

    def at(self, monotonic_ns: int) -> int:
        """Return the stamp time of monotonic ``monotonic_ns``."""
        return monotonic_ns + self.offset_ns


class SteppedClock(Clock):
    """A clock driven by hand: ``advance`` moves both clocks, ``step_wall`` only the wall one."""

    def __init__(self, monotonic_ns: int = 10**9, wall_offset_ns: int = 1_700_000_000 * 10**9):
        """Monotonic time and the wall clock's offset from it [ns]."""
        super().__init__()
        self.monotonic_ns = monotonic_ns
        self.wall_offset_ns = wall_offset_ns

    def wall_ns(self) -> int:
        """Return wall-clock time [ns]."""
        return self.monotonic_ns + self.wall_offset_ns

    def now_ns(self) -> int:
        """Return monotonic time [ns]."""
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
