# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The observer's input protocol.

Pair each measurement y(k) with the current u(k) commanded for it. Held by the ESO node and by the
offline loop (``actuator_sim.loop``). The observer holds x_hat(k); once y(k) and u(k) with the same
stamp t_k are both in, one step of (15) gives x_hat(k+1) (stamped t_k + dt), before y(k+1) exists
(docs/concepts/architecture.md#sample-timing). Pairing is by stamp, never "the latest message":
with the paper's gains the loop diverges when the observer integrates u(k-1)
(docs/paper-resolutions.md, 16).

A half of a pair that does not come in time is replaced: the step uses the last known current
(or, without a measurement, no correction) and says so. "In time" is ``patience_samples``:
1 in real time (a command later than a whole period missed its sample), longer in sim, where
nothing is lost and a PI controller can run ahead of the observer. A command that arrives
after its sample was stepped with a substitute repairs the state exactly, since (15) is
linear (``correction(du, steps)`` gives the change of the state ``steps`` steps later).

Bound to what it saw (actuator_core.binding): a command counts only for a measurement the
pairing received, or for the next sample (the controller may answer y(k+1) before this node has
it; the command then waits for its measurement); one stamped further ahead, or off the sample
grid, is refused with its reason (``refusal``) and takes no slot. Two different commands for
one sample (a second publisher) leave that sample to the substitute, and say so.

Work per call is bounded (``MAX_STEPS_PER_CALL``). Stamps are checked before they get here
(``actuator_core.timebase``); on a discontinuity (a restarted sensor, a new grid) the caller
calls ``restart``: the observer starts again from that measurement, as at start-up.
"""

from __future__ import annotations

from typing import Callable, NamedTuple, Optional, Protocol

from actuator_core.timebase import ahead_ns
from actuator_core.xmath import FloatOrArray

#: Unpaired samples kept of each kind; older ones are dropped.
PENDING_LIMIT = 256
#: Observer steps one incoming message may cause (a late half of a pair frees a few at most).
MAX_STEPS_PER_CALL = 16
#: Real time: wait one sample for the missing half; sim: up to this many (nothing is lost).
REALTIME_PATIENCE_SAMPLES = 1
SIM_PATIENCE_SAMPLES = 100
#: A command may be stamped up to this many samples after the newest measurement received.
COMMAND_AHEAD_SAMPLES = 1


class Observer(Protocol):
    """What the pairing drives: ``actuator_eso.observer.ExtendedStateObserver``."""

    def update(self, y, u) -> None:
        """x_hat(k) -> x_hat(k+1) with the pair (y(k), u(k))."""

    def reset(self, x_hat) -> None:
        """Start again from ``x_hat``."""

    def add(self, delta) -> None:
        """Add ``delta`` to the state."""

    @property
    def state(self) -> tuple:
        """(x1_hat, x2_hat, x3_hat)."""


class Estimate(NamedTuple):
    """x_hat for ``sample_ns`` and the pair it integrated (the fields of StateEstimate)."""

    sample_ns: int
    x_hat: tuple
    input_ns: int  # stamp of the pair integrated; 0 for an initial estimate
    input_position_rad: float
    input_current_a: float
    initial: bool  # x_hat(0) of a start or restart: integrated nothing yet
    substituted: bool  # the current of the pair was not in time; the last one was used


class ObserverInputPairing:
    """Pairs (y(k), u(k)) by stamp for one observer and steps it.

    Returns the estimates it produces.
    """

    def __init__(
        self,
        observer: Observer,
        period_ns: int,
        correction: Callable[[float, int], tuple],
        patience_samples: int = REALTIME_PATIENCE_SAMPLES,
        restart_gap_samples: Optional[int] = None,
    ):
        """``correction(du, steps)``.

        Change of x_hat ``steps`` steps after u(k) changed by du (eq. 15). With
        ``restart_gap_samples`` (real time), a measurement that many samples or more ahead of
        x_hat (the node stalled, its input was cut) restarts the observer from it: no back-fill
        of the gap with predictions.
        """
        self.observer = observer
        self.period_ns = period_ns
        self.correction = correction
        self.patience_ns = period_ns * patience_samples
        self.restart_gap_ns = (
            None if restart_gap_samples is None else restart_gap_samples * period_ns
        )
        self.gap_restarts = 0
        self.sample_ns: Optional[int] = None  # stamp x_hat is valid at
        self.measurements: dict[int, FloatOrArray] = {}
        self.currents: dict[int, FloatOrArray] = {}
        # current used in place of each missing command
        self.substitutes: dict[int, FloatOrArray] = {}
        self.newest_measurement_ns = -1
        self.last_current: FloatOrArray = 0.0
        self.steps = self.substituted = self.repaired = self.restarts = 0
        self.ignored = 0  # duplicates and samples older than x_hat's
        self.refused = self.conflicts = 0
        self.refusal = ''  # why the last command was refused ('' when it was not)
        self.conflicted: set[int] = set()  # samples two different commands claimed

    def add_measurement(self, stamp_ns: int, y) -> list[Estimate]:
        """y(k); the first one starts the observer there."""
        if self.sample_ns is None:
            return self.restart(stamp_ns, y)
        if stamp_ns < self.sample_ns or stamp_ns in self.measurements:
            self.ignored += 1
            return []
        if self.restart_gap_ns is not None and stamp_ns - self.sample_ns >= self.restart_gap_ns:
            self.gap_restarts += 1
            return self.restart(stamp_ns, y)
        self.measurements[stamp_ns] = y
        self.newest_measurement_ns = max(self.newest_measurement_ns, stamp_ns)
        return self._advance()

    def add_command(self, stamp_ns: int, u) -> list[Estimate]:
        """u(k), filed under the stamp of the sample it answers; a late one repairs the state.

        Refused ([] and ``refusal`` says why) beyond the newest measurement plus one sample,
        or off the sample grid.
        """
        self.refusal = ''
        if self.sample_ns is None:  # before the first measurement: kept for the start
            self.currents[stamp_ns] = u
            while len(self.currents) > PENDING_LIMIT:
                self.currents.pop(min(self.currents))
            return []
        ahead = ahead_ns(
            stamp_ns, self.newest_measurement_ns, COMMAND_AHEAD_SAMPLES, self.period_ns
        )
        off_grid = (stamp_ns - self.newest_measurement_ns) % self.period_ns
        if ahead is not None or off_grid:
            self.refused += 1
            self.refusal = f'command stamped {stamp_ns} ns refused: ' + (
                'off the sample grid'
                if off_grid or ahead is None
                else f'{ahead / 1e6:g} ms ahead of the newest measurement received'
            )
            return []
        if stamp_ns < self.sample_ns:
            self._repair(stamp_ns, u)
            return []
        if stamp_ns in self.conflicted:
            return []
        if stamp_ns in self.currents:
            if not _same(self.currents[stamp_ns], u):
                self.conflicts += 1
                self.conflicted.add(stamp_ns)
                del self.currents[stamp_ns]
                self.refusal = (
                    f'two different commands for sample {stamp_ns} ns (a second publisher?): '
                    'neither used, the sample is integrated with the last current'
                )
            else:
                self.ignored += 1
            return []
        self.currents[stamp_ns] = u
        return self._advance()

    def restart(self, stamp_ns: int, y) -> list[Estimate]:
        """(Re)start at sample ``stamp_ns`` from x_hat = (y, 0, 0).

        As the paper's x_hat(0) = 0 at y(0) = 0; then step at once if that sample's command is
        already in.
        """
        if self.sample_ns is not None:
            self.restarts += 1
        zero = 0.0 * y
        self.observer.reset((y, zero, zero))
        self.sample_ns = stamp_ns
        self.measurements.clear()
        self.currents = {
            s: u
            for s, u in self.currents.items()
            if stamp_ns <= s <= stamp_ns + COMMAND_AHEAD_SAMPLES * self.period_ns
        }
        self.substitutes.clear()
        self.conflicted.clear()
        self.newest_measurement_ns = stamp_ns
        self.measurements[stamp_ns] = y
        self.last_current = 0.0
        return [
            Estimate(stamp_ns, self.observer.state, 0, 0.0, 0.0, True, False)
        ] + self._advance()

    def _repair(self, stamp_ns: int, u) -> None:
        """Take a command for a sample already stepped with a substitute.

        Correct x_hat to the true pair.
        """
        used = self.substitutes.pop(stamp_ns, None)
        if used is None:
            return
        assert self.sample_ns is not None  # a substitute was used: x_hat has a stamp
        steps_since = (self.sample_ns - stamp_ns) // self.period_ns - 1
        self.observer.add(self.correction(u - used, steps_since))
        if steps_since == 0:
            self.last_current = u
        self.repaired += 1

    def _advance(self) -> list[Estimate]:
        """Step while the pair of the held sample is complete, or provably never will be."""
        assert self.sample_ns is not None  # restart gave x_hat a stamp
        out: list[Estimate] = []
        while len(out) < MAX_STEPS_PER_CALL:
            k = self.sample_ns
            y = self.measurements.pop(k, None)
            u = self.currents.pop(k, None)
            if (y is None or u is None) and self.newest_measurement_ns < k + self.patience_ns:
                if y is not None:
                    self.measurements[k] = y
                if u is not None:
                    self.currents[k] = u
                break
            substituted = u is None
            y_used = y if y is not None else self.observer.state[0]
            u_used = u if u is not None else self.last_current
            self.observer.update(y_used, u_used)
            self.steps += 1
            if substituted:
                self.substituted += 1
                self.substitutes[k] = u_used
            self.last_current = u_used
            self.sample_ns = k + self.period_ns
            out.append(
                Estimate(
                    self.sample_ns, self.observer.state, k, y_used, u_used, False, substituted
                )
            )
        for buffer in (self.measurements, self.currents, self.substitutes):
            while len(buffer) > PENDING_LIMIT:
                buffer.pop(min(buffer))
        if self.conflicted:
            self.conflicted = {s for s in self.conflicted if s >= self.sample_ns}
        return out


def _same(a, b) -> bool:
    """Whether two currents are equal (a batch: everywhere)."""
    equal = a == b
    return bool(equal.all()) if hasattr(equal, 'all') else bool(equal)
