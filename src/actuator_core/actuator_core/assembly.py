# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The controller's sample protocol: measurement + estimate + reference -> one command per sample.

Held by the controller node and by the offline loop (``actuator_sim.loop``). Sample k is
controlled as soon as y(k) and x_hat(k) (same stamp) are both in; PI needs no estimate.
An estimate whose pair was integrated with a substitute current is made exact first: the
observer is linear, so x2_hat + (commanded - substitute) * input_current_gain is the estimate
of the true pair (after one Euler step only x2_hat depends on u(k-1)).

Safety (statuses: ``actuator_core.status``): a non-finite output or |e| beyond the
following-error limit latches 0 A until ``reset``; ``watchdog`` answers stale inputs with
0 A; after ``resync`` (the sensor's time base jumped, the observer restarted, or an input
was silent for more than ``RESYNC_GAP_SAMPLES``) the command
is 0 A with safe stop (the drive's brake holds the joint) for ``resync_samples``, while the
observer converges on the new samples, and then the reference and the law restart from the
joint's angle: y_d(t - t_r) + q(t_r), so the run goes on as it would from a standstill. A
controller (re)started while the joint is away from y_d(0) starts its reference there too.

Scalars take the node's path; numpy arrays (a batch of offline runs) go through the same
arithmetic elementwise, the latch included.
"""

from __future__ import annotations

from typing import NamedTuple, Optional

from actuator_core import limits
from actuator_core import xmath as xm
from actuator_core.status import Status
from actuator_core.timing import sample_time_s

#: Estimates kept while waiting for their measurement.
PENDING_LIMIT = 64
#: A gap in an input stream this long (an observer or sensor restart whose first message was
#: lost, a cable drop) is handled as a resync: the joint was braked meanwhile, so the reference
#: restarts from where it is. Machine stalls (2-9 ms here) stay far below it.
RESYNC_GAP_SAMPLES = 100
#: Samples of 0 A after a resync: five time constants of the observer's poles at -c w0 = -300
#: rad/s (17 ms) and margin, so x2_hat and x3_hat have converged before control restarts.
RESYNC_SAMPLES = 50


class ControlSample(NamedTuple):
    """One sample's command and everything behind it (None where the law did not run)."""

    stamp_ns: int
    current_a: object
    status: object  # Status for a scalar run, an int array for a batch
    t_s: Optional[float]
    y: object
    estimate: Optional[tuple]  # (x2_hat, x3_hat) as used, after any correction
    reference: object  # ReferenceSample or None
    output: object  # ControlOutput or None


class ControlSampleAssembly:
    """Matches y(k) with x_hat(k), runs the law once per sample, guards its output."""

    def __init__(
        self,
        law,
        reference,
        period_ns: int,
        needs_estimate: bool = True,
        following_error_limit_rad: float = limits.FOLLOWING_ERROR_LIMIT_RAD,
        resync_samples: int = RESYNC_SAMPLES,
    ):
        """``law``: an actuator_controller.laws controller; ``reference``: has ``sample(t)``."""
        self.law = law
        self.reference = reference
        self.reference_offset_rad = None  # set by a restart after a resync
        self.period_ns = period_ns
        self.needs_estimate = needs_estimate
        self.following_error_limit_rad = following_error_limit_rad
        self.resync_samples = resync_samples
        self.estimates: dict[int, tuple] = {}
        self.commanded: tuple = (-1, 0.0)  # (stamp, current) of the newest command
        self.pending: Optional[tuple] = None  # (stamp, y) waiting for its estimate
        self.start_ns: Optional[int] = None  # reference t = 0
        self.newest_measurement_ns: Optional[int] = None
        self.newest_estimate_ns: Optional[int] = None
        self.latched = False
        self.resync_until_ns: Optional[int] = None
        self.corrected = self.unanswered = self.missed = self.resyncs = 0

    # --- inputs ---------------------------------------------------------------------------------
    def add_estimate(
        self,
        stamp_ns: int,
        x2_hat,
        x3_hat,
        input_ns: int = 0,
        input_current_a=0.0,
        input_current_gain=0.0,
        initial: bool = False,
    ) -> Optional[ControlSample]:
        """x_hat(k); an ``initial`` one after the start means the observer restarted.

        Resync (PI uses none).
        """
        if (
            self.start_ns is not None
            and self.needs_estimate
            and (initial or self._gap(self.newest_estimate_ns, stamp_ns))
        ):
            self.resync(stamp_ns)
        self.estimates[stamp_ns] = (x2_hat, x3_hat, input_ns, input_current_a, input_current_gain)
        self.newest_estimate_ns = (
            stamp_ns if self.newest_estimate_ns is None else max(self.newest_estimate_ns, stamp_ns)
        )
        while len(self.estimates) > PENDING_LIMIT:
            self.estimates.pop(min(self.estimates))
        return self._try_control()

    def add_measurement(self, stamp_ns: int, y) -> Optional[ControlSample]:
        """y(k): control sample k now, or as soon as x_hat(k) is in."""
        if self.start_ns is not None and self._gap(self.newest_measurement_ns, stamp_ns):
            self.resync(stamp_ns)
        if (
            self.newest_measurement_ns is not None
            and stamp_ns - self.newest_measurement_ns > self.period_ns * 3 // 2
        ):
            self.missed += (stamp_ns - self.newest_measurement_ns) // self.period_ns - 1
        self.newest_measurement_ns = stamp_ns
        if self.pending is not None:
            self.unanswered += 1  # the previous sample's estimate never came in time
        self.pending = (stamp_ns, y)
        return self._try_control()

    def _gap(self, newest_ns: Optional[int], stamp_ns: int) -> bool:
        """Return True on a gap of more than RESYNC_GAP_SAMPLES since ``newest_ns``."""
        return newest_ns is not None and stamp_ns - newest_ns > RESYNC_GAP_SAMPLES * self.period_ns

    def resync(self, stamp_ns: int) -> None:
        """Handle a time base jump at ``stamp_ns``.

        0 A and brake while the observer converges, then restart.
        """
        if self.resync_until_ns is not None and stamp_ns < self.resync_until_ns:
            return  # already resyncing
        self.resyncs += 1
        self.resync_until_ns = stamp_ns + self.resync_samples * self.period_ns
        self.estimates = {s: e for s, e in self.estimates.items() if s >= stamp_ns}
        if self.pending is not None and self.pending[0] < stamp_ns:
            self.pending = None

    def reset(self) -> None:
        """Clear the latch and start over (lifecycle: cleanup and configure)."""
        self.__init__(
            self.law,
            self.reference,
            self.period_ns,
            self.needs_estimate,
            self.following_error_limit_rad,
            self.resync_samples,
        )
        self.law.reset()

    # --- control --------------------------------------------------------------------------------
    def _try_control(self) -> Optional[ControlSample]:
        """Control the pending sample when its estimate is in (PI needs none)."""
        if self.pending is None:
            return None
        stamp, y = self.pending
        estimate = (0.0, 0.0)
        if self.needs_estimate:
            entry = self.estimates.pop(stamp, None)
            if entry is None:
                return None
            for old in [s for s in self.estimates if s < stamp]:
                del self.estimates[old]
            estimate = self._exact_estimate(*entry)
        self.pending = None
        return self._control(stamp, y, estimate)

    def _exact_estimate(self, x2, x3, input_ns, input_current, gain) -> tuple:
        """x_hat(k) as if the observer had integrated the current commanded for sample k-1."""
        stamp, current = self.commanded
        if input_ns != stamp or xm.all_true(current == input_current):
            return x2, x3
        self.corrected += 1
        return x2 + (current - input_current) * gain, x3

    def _control(self, stamp: int, y, estimate: tuple) -> ControlSample:
        """Run the law for sample ``stamp``; latch on a non-finite output or a following error."""
        if self.latched is True:
            return self.safe_sample(stamp, Status.LATCHED, y)
        if self.resync_until_ns is not None:
            if stamp < self.resync_until_ns:
                return self.safe_sample(stamp, Status.RESYNC, y)
            self.resync_until_ns = None
            self.reference_offset_rad = y - self.reference.sample(0.0).position_rad
            self.law.reset()
            self.start_ns = stamp
        if self.start_ns is None:  # the first sample: the reference starts from the joint's angle
            self.start_ns = stamp
            offset = y - self.reference.sample(0.0).position_rad
            if xm.any_true(
                offset != 0.0
            ):  # a restarted controller; the paper's runs start at 0 = y_d(0)
                self.reference_offset_rad = offset
        t = sample_time_s(stamp - self.start_ns)
        ref = self.reference.sample(t)
        if self.reference_offset_rad is not None:
            ref = ref._replace(position_rad=ref.position_rad + self.reference_offset_rad)
        out = self.law.update(t, y, estimate[0], estimate[1], ref)
        bad = xm.logical_not(out.finite) | (
            xm.fabs(out.error_rad) > self.following_error_limit_rad
        )
        self.latched = self.latched | bad
        current = xm.where(self.latched, 0.0, out.current_a)
        status = xm.where(self.latched, int(Status.LATCHED), int(Status.OK))
        if not isinstance(status, int):
            status = status.astype(int)
        else:
            status = Status(status)
        self.commanded = (stamp, current)
        return ControlSample(stamp, current, status, t, y, estimate, ref, out)

    def safe_sample(self, stamp_ns: int, status: Status, y=float('nan')) -> ControlSample:
        """0 A with ``status`` for sample ``stamp_ns`` (nothing from the law: no stale values)."""
        self.commanded = (stamp_ns, 0.0)
        return ControlSample(stamp_ns, 0.0, status, None, y, None, None, None)

    def watchdog(
        self, now_ns: int, measurement_timeout_ns: int, estimate_timeout_ns: int
    ) -> Optional[Status]:
        """STALE_MEASUREMENT or STALE_ESTIMATE when the newest input is older than its timeout.

        Else None.
        """
        if self.start_ns is None or self.latched is True:
            return None
        if (
            self.newest_measurement_ns is None
            or now_ns - self.newest_measurement_ns > measurement_timeout_ns
        ):
            return Status.STALE_MEASUREMENT
        if self.needs_estimate and (
            self.newest_estimate_ns is None
            or now_ns - self.newest_estimate_ns > estimate_timeout_ns
        ):
            return Status.STALE_ESTIMATE
        return None
