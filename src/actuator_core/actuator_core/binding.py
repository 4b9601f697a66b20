# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Bind every stamp to a sample the receiver has seen; refuse measurements no joint can make.

A command or estimate is an answer to one measurement sample. It counts only for a sample the
receiver saw happen (docs/safety.md#stamp-windows):
  ``SeenSamples``         the stamps a receiver has seen (the ESO and the controller: the
                          measurements they received) or produced (the joint: its own samples);
  ``CommandBinding``      the joint's rule: a current command only for one of its samples within
                          the command timeout (the newest k, or up to ``late_samples`` before
                          when late: 9 at 1 kHz), each sample once, never older than the
                          command applied; a safe stop for any sample of the last
                          ``safe_stop_samples`` (it only makes the joint safer, and repeats are
                          fine); anything ahead of the newest sample, or off its samples,
                          refused with the reason;
  ``MeasurementPlausibility``  a measurement whose implied velocity, or change of it, no joint
                          can make (``limits.VELOCITY_LIMIT_RAD_S``,
                          ``limits.ACCELERATION_LIMIT_RAD_S2``) is refused with its reason; a
                          step that persists is a real discontinuity and becomes the baseline.
Every check returns '' for an accepted input or a one-line reason; values come before stamps.
"""

from __future__ import annotations

from collections import deque
from typing import Optional

from actuator_core import limits
from actuator_core.timebase import ahead_ns

#: Samples of history a receiver keeps (1 s at 1 kHz).
SEEN_DEPTH = 1000


def late_window_samples(period_ns: int, timeout_s: float = limits.COMMAND_TIMEOUT_S) -> int:
    """Joint: how many samples before the newest a current command may answer (its late window).

    Those the drive's command timeout still covers: a command valid for the timeout from the sample
    it answers (the joint node offers it to the gate that much earlier) would otherwise be refused
    while the gate holds an older one for up to the timeout. Under normal scheduling the controller
    answers 2-11 samples late for tens of ms at a time (docs/safety.md#late-answers), and a joint
    that refused those answers held commands 2-16 ms old instead: the newest answer is never older
    than the command held. One sample of validity is kept, so at least one before.
    """
    return max(1, int(round(timeout_s * 1e9)) // period_ns - 1)


#: Joint: a safe stop may answer any of the newest this many samples (the controller's watchdog
#: stamps its stop with the newest measurement it saw, which may be some samples old).
SAFE_STOP_SAMPLES = 100
#: Noise allowance of the plausibility check [rad]: a 16-bit-per-revolution encoder's quantum.
POSITION_NOISE_RAD = 1.0e-4
#: Beyond this gap [s] the velocity before it says nothing about the velocity after it.
PLAUSIBILITY_MEMORY_S = 0.1


class SeenSamples:
    """The newest ``depth`` stamps a node has seen or produced, newest first in time."""

    def __init__(self, period_ns: int, depth: int = SEEN_DEPTH):
        """``period_ns``: the sample grid's period."""
        self.period_ns = period_ns
        self.depth = depth
        self._order: deque[int] = deque()
        self._set: set[int] = set()
        self.newest_ns: Optional[int] = None

    def add(self, stamp_ns: int) -> None:
        """Record a sample seen (or produced); a stamp older than the newest is kept too."""
        if stamp_ns in self._set:
            return
        self._order.append(stamp_ns)
        self._set.add(stamp_ns)
        if self.newest_ns is None or stamp_ns > self.newest_ns:
            self.newest_ns = stamp_ns
        while len(self._order) > self.depth:
            self._set.discard(self._order.popleft())

    def __contains__(self, stamp_ns: int) -> bool:
        """Whether ``stamp_ns`` is one of the samples kept."""
        return stamp_ns in self._set

    def ahead(self, stamp_ns: int, allowed_samples: int = 0) -> str:
        """Return why ``stamp_ns`` is beyond the newest sample plus ``allowed_samples``, or ''."""
        if self.newest_ns is None:
            return 'no sample seen yet'
        ahead = ahead_ns(stamp_ns, self.newest_ns, allowed_samples, self.period_ns)
        if ahead is not None:
            newest = self.newest_ns
            return f'stamped {ahead / 1e6:.3f} ms ahead of the newest sample seen ({newest} ns)'
        return ''

    def reset(self) -> None:
        """Forget every sample (lifecycle cleanup, a restarted time base)."""
        self._order.clear()
        self._set.clear()
        self.newest_ns = None


class CommandBinding:
    """The joint accepts a command only for a sample it produced itself (the integrator's API).

    Call ``produced(stamp)`` for every sample published, ``check(stamp, safe_stop)`` for every
    command before the gate sees it ('' accepted, else the reason to log and ignore it), and
    ``reset()`` at activation.
    """

    def __init__(
        self,
        period_ns: int,
        late_samples: Optional[int] = None,
        safe_stop_samples: int = SAFE_STOP_SAMPLES,
    ):
        """Windows in samples of ``period_ns`` (default late window: ``late_window_samples``)."""
        self.period_ns = period_ns
        if late_samples is None:
            late_samples = late_window_samples(period_ns)
        self.late_samples = late_samples
        self.samples = SeenSamples(period_ns, max(safe_stop_samples, late_samples + 1))
        self.applied_ns: Optional[int] = None  # stamp of the newest current command accepted
        self.refused = 0

    def produced(self, stamp_ns: int) -> None:
        """Record that the joint published sample ``stamp_ns``."""
        self.samples.add(stamp_ns)

    def valid_from_ns(self, stamp_ns: int, safe_stop: bool, now_ns: int) -> int:
        """When the gate's timeout starts for a command accepted at ``now_ns``.

        A current answering a sample before the newest: earlier by the samples it is late (valid
        for the command timeout from the sample it answers, ``late_window_samples``); a safe stop
        and a current for the newest sample: at once.
        """
        newest = self.samples.newest_ns
        if safe_stop or newest is None:
            return now_ns
        return now_ns - max(0, newest - stamp_ns)

    def check(self, stamp_ns: int, safe_stop: bool) -> str:
        """'' when a command stamped ``stamp_ns`` may be applied, else why not."""
        why = self._why(stamp_ns, safe_stop)
        if why:
            self.refused += 1
        elif not safe_stop:
            self.applied_ns = stamp_ns
        return why

    def _why(self, stamp_ns: int, safe_stop: bool) -> str:
        """Return the reason, without counting."""
        kind = 'safe stop' if safe_stop else 'command'
        ahead = self.samples.ahead(stamp_ns)
        if ahead:
            return f'{kind} {ahead}: refused'
        if stamp_ns not in self.samples:
            return f'{kind} stamped {stamp_ns} ns answers no sample this joint produced: refused'
        if safe_stop:
            return ''
        newest = self.samples.newest_ns
        assert newest is not None  # stamp_ns is one of the samples
        oldest = newest - self.late_samples * self.period_ns
        if stamp_ns < oldest:
            age_ms = (newest - stamp_ns) / 1e6
            return (
                f'command for sample {stamp_ns} ns is {age_ms:g} ms old (the window is the '
                f'newest sample and {self.late_samples} before): refused'
            )
        if self.applied_ns is not None and stamp_ns <= self.applied_ns:
            return (
                f'command for sample {stamp_ns} ns is not newer than the one applied '
                f'({self.applied_ns} ns; a duplicate or a replay): refused'
            )
        return ''

    def reset(self) -> None:
        """Forget every sample and command (activation)."""
        self.samples.reset()
        self.applied_ns = None


class MeasurementPlausibility:
    """Refuses measurements whose implied velocity or acceleration no joint can make.

    ``check`` is pure; then the caller calls ``accept`` (the sample was taken), ``refuse``
    (True when a persisting step is confirmed as a new baseline: handle it as a restart), or
    ``rebase`` (a restarted time base: start from this sample).
    """

    def __init__(
        self,
        velocity_limit_rad_s: float = limits.VELOCITY_LIMIT_RAD_S,
        acceleration_limit_rad_s2: float = limits.ACCELERATION_LIMIT_RAD_S2,
        confirm_samples: int = limits.PLAUSIBILITY_CONFIRM_SAMPLES,
        noise_rad: float = POSITION_NOISE_RAD,
    ):
        """Limits from actuator_core.limits."""
        self.velocity_limit = velocity_limit_rad_s
        self.acceleration_limit = acceleration_limit_rad_s2
        self.confirm_samples = confirm_samples
        self.noise_rad = noise_rad
        self.reset()

    def reset(self) -> None:
        """No baseline (the next measurement becomes it)."""
        self.last: Optional[tuple] = None  # (stamp, y) of the newest accepted measurement
        self.velocity: Optional[tuple] = None  # (implied velocity, its interval [s])
        self.candidates: list[tuple] = []
        self.refused = self.rebases = 0

    def _implied(self, last: tuple, stamp_ns: int, y: float) -> tuple:
        """(velocity, interval) from ``last`` to (stamp, y)."""
        dt = (stamp_ns - last[0]) * 1e-9
        return (y - last[1]) / dt, dt

    def check(self, stamp_ns: int, y: float) -> str:
        """'' or why y at ``stamp_ns`` is not a measurement of this joint (no state change)."""
        if self.last is None or stamp_ns <= self.last[0]:
            return ''  # the first one, or a stamp the stamp check will sort out
        return self._why(self.last, self.velocity, stamp_ns, y)

    def _why(self, last, velocity, stamp_ns, y) -> str:
        """Run the checks of ``check`` against a given baseline."""
        v, dt = self._implied(last, stamp_ns, y)
        if abs(v) > self.velocity_limit + 2.0 * self.noise_rad / dt:
            return (
                f'measurement {y:.6g} rad implies {v:.4g} rad/s since the last one accepted '
                f'(limit {self.velocity_limit:g} rad/s): refused'
            )
        if velocity is not None and dt <= PLAUSIBILITY_MEMORY_S:
            v0, dt0 = velocity
            allowed = self.acceleration_limit * 0.5 * (dt0 + dt) + 4.0 * self.noise_rad / dt
            if abs(v - v0) > allowed:
                return (
                    f'measurement {y:.6g} rad changes the implied velocity by {v - v0:.4g} rad/s '
                    f'in {dt * 1e3:g} ms (limit {self.acceleration_limit:g} rad/s^2): refused'
                )
        return ''

    def accept(self, stamp_ns: int, y: float) -> None:
        """Take the sample as the new baseline."""
        if self.last is not None and stamp_ns > self.last[0]:
            v, dt = self._implied(self.last, stamp_ns, y)
            self.velocity = (v, dt) if dt <= PLAUSIBILITY_MEMORY_S else None
        self.last = (stamp_ns, y)
        self.candidates.clear()

    def refuse(self, stamp_ns: int, y: float) -> bool:
        """Count a refused sample; True when ``confirm_samples`` of them agree (a real step)."""
        self.refused += 1
        if self.candidates and not (
            stamp_ns > self.candidates[-1][0]
            and not self._why(self.candidates[-1], None, stamp_ns, y)
        ):
            self.candidates.clear()
        self.candidates.append((stamp_ns, y))
        if len(self.candidates) < self.confirm_samples:
            return False
        self.rebase(stamp_ns, y)
        return True

    def rebase(self, stamp_ns: int, y: float) -> None:
        """Start from this sample (a restarted time base, or a confirmed step)."""
        self.rebases += 1
        self.last, self.velocity = (stamp_ns, y), None
        self.candidates.clear()
