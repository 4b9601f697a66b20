# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The time base of one input stream.

Every stamp is checked against the receiver's clock and the sample grid. Held by each node for each
1 kHz input. ``check`` sorts a stamp into:
  OK       the next sample, or a later one on the same grid (missed samples are not an error);
  FUTURE   real time: beyond the receiver's stamp time (actuator_core.clock.StampClock, which a
           wall-clock step leaves) plus ``future_tolerance_ns``; sim: beyond the next expected
           sample. Refused, never integrated: one stamp 1000 s ahead used to end control for
           good. But a stream of ``FUTURE_STREAM_SAMPLES`` stamps one period apart, all ahead,
           is a sender whose time base is ahead of the receiver's (a joint restarted after a
           step of the wall clock): a JUMP, and the receiver adopts it;
  OLD      a duplicate or an out-of-order sample a little in the past: ignored;
  JUMP     a discontinuity (a restarted sensor or driver): off the grid, or back in time (by
           more than ``jump_samples`` in real time, by any amount in sim, where nothing comes
           late), or ahead by more than ``jump_samples``. The stamp becomes the new grid
           origin and the receiver applies its restart policy (docs/safety.md#recovery-policy);
  INVALID  negative, or beyond ``limits.STAMP_MAX_NS`` (builtin_interfaces/Time's int32 seconds
           would overflow on the stamps a node derives from it): refused.
A caller may pass ``limit_ns``, the newest stamp it may accept (the newest measurement it has
seen, plus what the protocol allows): beyond it the verdict is FUTURE, in every mode. A refused
stamp (FUTURE, INVALID) never becomes the stream's newest. Values are checked by the caller
before the stamp is: a refused value never gets here.
"""

from __future__ import annotations

from enum import Enum
from typing import Optional

from actuator_core.limits import STAMP_MAX_NS

#: Samples back (or, in real time, ahead) that count as a restarted time base, not jitter.
JUMP_SAMPLES = 1000
#: Stamps in a row, one period apart and each ahead of the receiver's stamp time, that make a
#: time base ahead of the receiver's, not a stray stamp: 50 ms of samples.
FUTURE_STREAM_SAMPLES = 50


def ahead_ns(stamp_ns: int, newest_ns: int, allowed_samples: int, period_ns: int) -> Optional[int]:
    """Return how far [ns] ``stamp_ns`` is ahead of ``newest_ns``, when beyond the allowed samples.

    The one "ahead" rule of the protocol: a stamp more than ``allowed_samples`` periods after
    the newest sample a receiver saw is none it can answer (the joint's commands, the observer's
    commands, the controller's estimates); None when it is within them.
    """
    if stamp_ns > newest_ns + allowed_samples * period_ns:
        return stamp_ns - newest_ns
    return None


class Verdict(Enum):
    """What a stamp is."""

    OK = 'ok'
    FUTURE = 'future'
    OLD = 'old'
    JUMP = 'jump'
    INVALID = 'invalid'


class StampCheck:
    """One stream's stamps: grid, clock, discontinuities; counts what it refused."""

    def __init__(
        self, period_ns: int, sim: bool, future_tolerance_ns: int, jump_samples: int = JUMP_SAMPLES
    ):
        """``sim``: the next expected sample bounds the future; else the receiver's clock does."""
        self.period_ns = period_ns
        self.sim = sim
        self.future_tolerance_ns = future_tolerance_ns
        self.jump_ns = jump_samples * period_ns
        self.last_ns: Optional[int] = None
        self.future_run = 0  # stamps in a row ahead of the receiver's stamp time, on a grid
        self.future_last_ns: Optional[int] = None
        self.refused_future = self.ignored_old = self.jumps = self.invalid = 0

    def check(self, stamp_ns: int, now_ns: int, limit_ns: Optional[int] = None) -> Verdict:
        """Return the verdict on ``stamp_ns``.

        ``now_ns``: the receiver's stamp time when the stamp was received (real time:
        actuator_core.clock.StampClock, the wall clock's time kept on the monotonic clock);
        ``limit_ns`` the newest stamp the receiver may accept (None: no such bound).
        """
        if stamp_ns < 0 or stamp_ns > STAMP_MAX_NS:
            self.invalid += 1
            return Verdict.INVALID
        if limit_ns is not None and ahead_ns(stamp_ns, limit_ns, 0, self.period_ns) is not None:
            self.refused_future += 1
            return Verdict.FUTURE
        if not self.sim and stamp_ns > now_ns + self.future_tolerance_ns:
            return self._ahead(stamp_ns)
        self.future_run = 0
        last = self.last_ns
        if last is None:
            self.last_ns = stamp_ns
            return Verdict.OK
        if self.sim and stamp_ns > last + self.period_ns:
            self.refused_future += 1
            return Verdict.FUTURE
        ahead = stamp_ns - last
        back = -self.period_ns if self.sim else -self.jump_ns  # sim: nothing is late or duplicated
        if (ahead % self.period_ns != 0) or ahead <= back or ahead > self.jump_ns:
            self.jumps += 1
            self.last_ns = stamp_ns
            return Verdict.JUMP
        if ahead <= 0:
            self.ignored_old += 1
            return Verdict.OLD
        self.last_ns = stamp_ns
        return Verdict.OK

    def _ahead(self, stamp_ns: int) -> Verdict:
        """Judge a stamp ahead of stamp time: FUTURE, or JUMP when it ends a stream of them."""
        on_grid = self.future_last_ns is not None and stamp_ns - self.future_last_ns == (
            self.period_ns
        )
        self.future_run = self.future_run + 1 if on_grid else 1
        self.future_last_ns = stamp_ns
        if self.future_run < FUTURE_STREAM_SAMPLES:
            self.refused_future += 1
            return Verdict.FUTURE
        self.future_run = 0
        self.jumps += 1
        self.last_ns = stamp_ns
        return Verdict.JUMP

    def reset(self) -> None:
        """Forget the grid (lifecycle cleanup)."""
        self.last_ns = None
        self.future_run = 0
