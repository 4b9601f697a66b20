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
was silent for more than ``gap_limit_samples``, the drive's command timeout) the command
is 0 A with safe stop (the drive's brake holds the joint) for ``resync_samples``, while the
observer converges on the new samples, and then the reference and the law restart from the
joint's angle at the reference's first rest t_0 (``first_rest_s``): y_d(t - t_r + t_0) -
y_d(t_0) + q(t_r), so a braked joint starts onto a reference at rest, not one already moving
(the paper's trajectory starts at -0.35 rad/s: a step the law answered at the limit). A
controller (re)started while the joint is away from y_d(0) starts its reference there too. A
commanded reference (``reference: hold``, actuator_controller.commanded_reference) restarts
as a hold of the joint's angle instead (``_restart_reference``).

Bound to what it saw (actuator_core.binding): an estimate counts only for the newest
measurement received or the next one (x_hat(k+1) is made before y(k+1) exists); one stamped
further ahead is refused with its reason and moves nothing. Two different estimates for one
sample (a second publisher racing the observer) are both dropped: that sample gets 0 A.

The supervision is one explicit state (``Supervision``: running, answered, braked, stalled,
resync), its transitions in this class; the latch is apart (elementwise for a batch).

Recovery policy (docs/safety.md#recovery-policy), every gap alike: a stale input is answered in
grades by ``watchdog``: up to its timeout nothing (the drive holds the last command), then 0 A
without the brake, and 0 A with the brake once the input is ``brake_after`` old; a brake a safe
stop engaged (a resync, the watchdog's own) stays until the law commands again. When the law is to
run again after more than ``gap_limit_samples`` (the drive's command timeout: the joint was braked
by its gate or by this watchdog) without a law sample, after the node itself sent no command that
long (``command_gap``: a stalled node sees no gap in the stamps it then reads), or after the
watchdog braked the joint (an input that old: the stamps the law runs on next may show no gap, e.g.
a stalled joint replaying its samples), the resync path runs instead: no chase of the error the
reference accumulated meanwhile.
After a resync, and after a shorter gap the watchdog answered, the law's samples say
RECOVERING for ``RECOVERY_SAMPLES``, and always while |e| is outside the prescribed envelope:
a state never says OK there. Ages are measured on the receiver's monotonic clock
(``received_ns`` of each input; the stamp itself in sim and offline, where stamps are the
clock).

Scalars take the node's path; numpy arrays (a batch of offline runs) go through the same
arithmetic elementwise, the latch included.
"""

from __future__ import annotations

from enum import Enum
from typing import Any, NamedTuple, Optional

import numpy as np

from actuator_core import limits
from actuator_core import xmath as xm
from actuator_core.status import Status
from actuator_core.timebase import ahead_ns
from actuator_core.timing import sample_time_s
from actuator_core.xmath import FloatOrArray

#: Estimates kept while waiting for their measurement.
PENDING_LIMIT = 64
#: Samples of 0 A after a resync: five time constants of the observer's poles at -c w0 = -300
#: rad/s (17 ms) and margin, so x2_hat and x3_hat have converged before control restarts.
RESYNC_SAMPLES = 50
#: Samples in a row the law's command may sit at the current limit and the state still say OK
#: ("a handful": a step of the reference or a brief disturbance); from the next, RECOVERING
#: until the command leaves the limit (a loop chattering at the limit is never OK).
AT_LIMIT_SAMPLES = 5
#: Samples after the law restarts (a resync, a short gap) that say RECOVERING.
RECOVERY_SAMPLES = RESYNC_SAMPLES
#: A resync also waits until x2_hat says the braked joint is at rest [rad/s], at most
#: RESYNC_MAX_SAMPLES in all: a drive's brake closes in about 20 ms and a joint coming from the
#: fast trajectory's 8.8 rad/s slides for up to 60 ms, so after 50 samples it could still move at
#: 3 rad/s, and the law restarted on a reference at rest stopped it at the current limit (9
#: samples through the simulated drive). Below this the law's first commands stay off the limit.
RESYNC_REST_VELOCITY_RAD_S = 0.5
RESYNC_MAX_SAMPLES = 300
#: Held in place of an estimate two publishers claimed differently.
CONFLICTED = ('conflicted',)
#: An estimate may be stamped up to this many samples after the newest measurement seen.
ESTIMATE_AHEAD_SAMPLES = 1
#: How far [s] a restart looks for the reference's first rest (``first_rest_s``).
REST_HORIZON_S = 1.0


class Supervision(Enum):
    """What the loop's supervision holds between the law's samples (docs/safety.md).

    The transitions, all in ``ControlSampleAssembly``: ``watchdog`` answers a stale input
    (ANSWERED; BRAKED once an answer asked for the brake), ``command_gap`` notices a stall of the
    node itself (STALLED), ``resync`` holds 0 A and the brake (RESYNC, until
    ``resync_until_ns`` and the joint at rest). At the law's next sample: from BRAKED or STALLED,
    or after a gap beyond the drive's command timeout, the resync runs; from ANSWERED the law
    goes on saying RECOVERING for RECOVERY_SAMPLES; RESYNC ends in a restart of the reference and
    the law. The latch (a non-finite output or a following error) is apart: it holds 0 A until
    ``reset``, elementwise for a batch of offline runs.
    """

    RUNNING = 'running'  #: the law runs for each sample
    ANSWERED = 'answered'  #: the watchdog answered with 0 A, no brake: a short gap so far
    BRAKED = 'braked'  #: a watchdog answer braked the joint: the law's next sample resyncs
    STALLED = 'stalled'  #: this node sent nothing beyond the drive's timeout: resync next
    RESYNC = 'resync'  #: 0 A and brake while the observer converges, then restart


def gap_limit_samples(period_ns: int) -> int:
    """Return the samples without a law sample after which the resync runs (command timeout)."""
    return max(1, int(round(limits.COMMAND_TIMEOUT_S * 1e9 / period_ns)))


#: An estimate kept for its sample: (x2_hat, x3_hat, input_ns, input_current_a,
#: input_current_gain), the arguments of ``ControlSampleAssembly.add_estimate``.
EstimateEntry = tuple[FloatOrArray, FloatOrArray, Optional[int], FloatOrArray, FloatOrArray]


class ControlSample(NamedTuple):
    """One sample's command and everything behind it (None where the law did not run)."""

    stamp_ns: int
    current_a: FloatOrArray
    status: Any  # Status for a scalar run, an int array for a batch
    t_s: Optional[float]
    y: FloatOrArray
    estimate: Optional[tuple]  # (x2_hat, x3_hat) as used, after any correction
    reference: Any  # actuator_controller's ReferenceSample, or None
    output: Any  # actuator_controller's ControlOutput, or None
    safe_stop: bool = False  # the command asks the drive for 0 A and the brake
    #: False: the joint already applies a command for this sample and takes only a safe stop in
    #: its place (actuator_core.binding.CommandBinding), so no command is sent, only the state
    command: bool = True


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
        brake_after_s: float = limits.BRAKE_AFTER_S,
    ):
        """``law``: an actuator_controller.laws controller; ``reference``: has ``sample(t)``."""
        self.law = law
        self.reference = reference
        self.reference_offset_rad = None  # set by a restart after a resync
        self.reference_shift_s = 0.0  # t_0 once a resync restarted the reference
        self.rest_s = first_rest_s(reference, period_ns)  # the reference's first rest t_0
        self.period_ns = period_ns
        self.needs_estimate = needs_estimate
        self.following_error_limit_rad = following_error_limit_rad
        self.resync_samples = resync_samples
        self.resync_extra_ns = max(0, RESYNC_MAX_SAMPLES - resync_samples) * period_ns
        self.brake_after_s = brake_after_s
        self.brake_after_ns = int(round(brake_after_s * 1e9))
        self.gap_limit_ns = gap_limit_samples(period_ns) * period_ns
        self.estimates: dict[int, tuple] = {}
        self.commanded: Optional[tuple] = None  # (stamp, current) of the newest command
        self.pending: Optional[tuple] = None  # (stamp, y) waiting for its estimate
        self.start_ns: Optional[int] = None  # reference t = 0
        self.newest_measurement_ns: Optional[int] = None
        self.newest_estimate_ns: Optional[int] = None
        self.measurement_received_ns: Optional[int] = None  # monotonic receipt of the newest
        self.estimate_received_ns: Optional[int] = None
        self.controlled_ns: Optional[int] = None  # stamp of the newest sample the law ran for
        self.supervision = Supervision.RUNNING
        self.recovering_until_ns: Optional[int] = None
        self.latched = False
        self.braking = False  # the newest command asked for the brake (safe_stop)
        self.resync_until_ns: Optional[int] = None  # RESYNC: 0 A and brake up to this stamp
        # a stall's hold on the receipt clock too: as many periods from when it was noticed
        self.resync_until_received_ns = 0
        self.stall_noticed_ns: Optional[int] = None  # receipt clock: when a stall was noticed
        self.refusal = ''  # why the last input was refused ('' when it was not)
        # an observer restart ahead of y, kept aside: (stamp, entry, received_ns)
        self.initial_ahead: Optional[tuple[int, EstimateEntry, Optional[int]]] = None
        self.at_limit_run = 0  # the law's samples in a row at the current limit, up to now
        self.corrected = self.unanswered = self.missed = self.resyncs = 0
        self.refused = self.conflicts = self.gap_resyncs = 0

    # --- inputs ---------------------------------------------------------------------------------
    def add_estimate(
        self,
        stamp_ns: int,
        x2_hat,
        x3_hat,
        input_ns: Optional[int] = None,
        input_current_a=0.0,
        input_current_gain=0.0,
        initial: bool = False,
        received_ns: Optional[int] = None,
    ) -> Optional[ControlSample]:
        """x_hat(k), received at monotonic ``received_ns`` (default: its stamp).

        ``input_ns``, ``input_current_a``, ``input_current_gain``: the command the observer
        integrated into it and that current's gain in x2_hat (None: it names none, and is
        never corrected).

        Refused (None, ``refusal`` says why) when stamped beyond the newest measurement seen
        plus one sample. An ``initial`` one after the start means the observer restarted:
        resync (PI uses none).
        """
        entry: EstimateEntry = (x2_hat, x3_hat, input_ns, input_current_a, input_current_gain)
        self.refusal = input_stamp_refusal(stamp_ns, input_ns)
        if self.refusal:  # not the observer's own: no restart is kept aside either
            self.refused += 1
            return None
        self.refusal = self.estimate_refusal(stamp_ns)
        if self.refusal:
            self.refused += 1
            if initial:  # a restarted observer may be ahead of this node's measurements
                self.initial_ahead = (stamp_ns, entry, received_ns)
                self.refusal += '; kept aside as a restart, used if that measurement comes'
            return None
        held = self.estimates.get(stamp_ns)
        if held is not None and not initial and not _same(held, entry):
            self.conflicts += 1
            self.estimates[stamp_ns] = CONFLICTED  # neither is trusted: the sample gets 0 A
            self.refusal = (
                f'two different estimates for sample {stamp_ns} ns (a second publisher?): '
                'neither used, 0 A for that sample'
            )
            return None
        if self.start_ns is not None and self.needs_estimate and initial:
            self.resync(stamp_ns)
        self.estimates[stamp_ns] = entry
        if self.newest_estimate_ns is None or stamp_ns >= self.newest_estimate_ns:
            self.newest_estimate_ns = stamp_ns
            self.estimate_received_ns = stamp_ns if received_ns is None else received_ns
        while len(self.estimates) > PENDING_LIMIT:
            self.estimates.pop(min(self.estimates))
        return self._try_control()

    def estimate_refusal(self, stamp_ns: int) -> str:
        """'' when an estimate stamped ``stamp_ns`` answers a measurement seen, else why not."""
        newest = self.newest_measurement_ns
        ahead = (
            None
            if newest is None
            else ahead_ns(stamp_ns, newest, ESTIMATE_AHEAD_SAMPLES, self.period_ns)
        )
        if ahead is not None:
            return (
                f'estimate stamped {stamp_ns} ns refused: {ahead / 1e6:g} ms ahead '
                f'of the newest measurement seen (at most {ESTIMATE_AHEAD_SAMPLES} sample)'
            )
        return ''

    def add_measurement(
        self, stamp_ns: int, y, received_ns: Optional[int] = None
    ) -> Optional[ControlSample]:
        """y(k) received at monotonic ``received_ns``: control k now, or once x_hat(k) is in."""
        if (
            self.newest_measurement_ns is not None
            and stamp_ns - self.newest_measurement_ns > self.period_ns * 3 // 2
        ):
            self.missed += (stamp_ns - self.newest_measurement_ns) // self.period_ns - 1
        self.newest_measurement_ns = stamp_ns
        self.measurement_received_ns = stamp_ns if received_ns is None else received_ns
        if self.pending is not None:
            self.unanswered += 1  # the previous sample's estimate never came in time
        self.pending = (stamp_ns, y)
        if self.initial_ahead is not None and self.initial_ahead[0] <= stamp_ns:
            restart, self.initial_ahead = self.initial_ahead, None
            if restart[0] == stamp_ns:  # the observer's restart was for this very sample
                return self.add_estimate(
                    stamp_ns, *restart[1], initial=True, received_ns=restart[2]
                )
        return self._try_control()

    def resync(self, stamp_ns: int) -> None:
        """Handle a time base jump at ``stamp_ns``.

        0 A and brake while the observer converges, then restart.
        """
        until_ns = self.resync_until_ns  # set while resyncing
        if self.supervision is Supervision.RESYNC and until_ns is not None and stamp_ns < until_ns:
            return  # already resyncing
        self.resyncs += 1
        self.supervision = Supervision.RESYNC
        hold_ns = self.resync_samples * self.period_ns
        self.resync_until_ns = stamp_ns + hold_ns
        # A stall caught this node with the sample in hand (received long before the stall was
        # noticed): its stamp is from before the stall, so the hold counts from waking too.
        noticed, received = self.stall_noticed_ns, self.measurement_received_ns
        self.resync_until_received_ns = 0
        if noticed is not None and received is not None and noticed - received > self.gap_limit_ns:
            self.resync_until_received_ns = noticed + hold_ns
        self.estimates = {s: e for s, e in self.estimates.items() if s >= stamp_ns}
        if self.pending is not None and self.pending[0] < stamp_ns:
            self.pending = None
        self.controlled_ns = None

    def _latest_received_ns(self, default_ns: int) -> int:
        """Return the latest input receipt time known, else ``default_ns``."""
        known = [t for t in (self.measurement_received_ns, self.estimate_received_ns) if t]
        return max(known) if known else default_ns

    def command_gap(self, silent_ns: int, quiet_ns: int = 0, now_ns: Optional[int] = None) -> None:
        """Take note that no command went out for ``silent_ns`` [ns] (a stall of this node).

        Its stamps show no gap then. ``quiet_ns``: the longest this node is silent by design
        (its watchdog answers a stale input within its timeout and one period). A silence
        beyond both that and the drive's command timeout is a stall, and the joint was braked:
        the next sample the law is to run for takes the resync path instead of chasing the
        reference (that sample, not the newest seen: the watchdog's timer may notice the stall
        first, when the newest stamp is from before it, and a hold counted from there would
        be over before it began). ``now_ns``: when the stall was noticed, on the receipt clock;
        when the stall caught the node with a sample in hand (received before it), the hold also
        lasts ``resync_samples`` periods from then.
        """
        if silent_ns > max(self.gap_limit_ns, quiet_ns) and self.controlled_ns is not None:
            self.supervision = Supervision.STALLED  # the resync starts at the law's next sample
            self.stall_noticed_ns = now_ns

    def reset(self) -> None:
        """Clear the latch and start over (lifecycle: cleanup and configure)."""
        ControlSampleAssembly.__init__(
            self,
            self.law,
            self.reference,
            self.period_ns,
            self.needs_estimate,
            self.following_error_limit_rad,
            self.resync_samples,
            self.brake_after_s,
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
            self.pending = None
            if entry is CONFLICTED:  # two publishers' estimates for this sample
                return self.safe_sample(stamp, Status.INVALID_INPUT, y, safe_stop=False)
            estimate = self._exact_estimate(*entry)
            vmax = limits.VELOCITY_LIMIT_RAD_S  # a non-finite one goes on to the latch
            if _scalar(estimate[0]) and xm.isfinite(estimate[0]) and abs(estimate[0]) > vmax:
                self.refused += 1
                self.refusal = (
                    f'estimate for {stamp} ns refused: x2_hat corrected for the current '
                    f'commanded is {estimate[0]:.4g} rad/s, beyond +-{vmax:g}'
                )
                return self.safe_sample(stamp, Status.INVALID_INPUT, y, safe_stop=False)
        self.pending = None
        return self._control(stamp, y, estimate)

    def _exact_estimate(self, x2, x3, input_ns, input_current, gain) -> tuple:
        """x_hat(k) as if the observer had integrated the current commanded for sample k-1."""
        if self.commanded is None:  # no command yet: nothing to correct for
            return x2, x3
        stamp, current = self.commanded
        if input_ns != stamp or xm.all_true(current == input_current):
            return x2, x3
        self.corrected += 1
        return x2 + (current - input_current) * gain, x3

    def _control(self, stamp: int, y, estimate: tuple) -> ControlSample:
        """Run the law for sample ``stamp``; latch on a non-finite output or a following error."""
        if self.latched is True:
            return self.safe_sample(stamp, Status.LATCHED, y)
        braked = self.supervision in (Supervision.BRAKED, Supervision.STALLED)
        if self.controlled_ns is not None and (
            stamp - self.controlled_ns > self.gap_limit_ns or braked
        ):
            self.gap_resyncs += 1  # the joint was braked: no chase of what the reference ran on
            self.resync(stamp)
        elif self.supervision is Supervision.ANSWERED:
            self._recover_until(stamp)  # a short gap: the law goes on, saying RECOVERING
        if self.supervision is not Supervision.RESYNC:
            self.supervision = Supervision.RUNNING
        else:
            sliding = self.needs_estimate and xm.any_true(
                xm.fabs(estimate[0]) > RESYNC_REST_VELOCITY_RAD_S
            )
            received_ns = self._latest_received_ns(stamp)
            until_ns = self.resync_until_ns
            assert until_ns is not None  # resync set it
            if (
                stamp < until_ns
                or received_ns < self.resync_until_received_ns
                or (sliding and stamp < until_ns + self.resync_extra_ns)
            ):
                return self.safe_sample(stamp, Status.RESYNC, y)
            self.supervision = Supervision.RUNNING
            self.resync_until_ns = self.stall_noticed_ns = None
            self._restart_reference(y, self.rest_s)
            self.law.reset()
            self.at_limit_run = 0
            self.start_ns = stamp
            self._recover_until(stamp)
        self.controlled_ns = stamp
        if self.start_ns is None:  # the first sample: the reference starts from the joint's angle
            self.start_ns = stamp
            self._restart_reference(y, None)
        t = sample_time_s(stamp - self.start_ns)
        ref = self.reference.sample(t + self.reference_shift_s)
        if self.reference_offset_rad is not None:
            ref = ref._replace(position_rad=ref.position_rad + self.reference_offset_rad)
        out = self.law.update(t, y, estimate[0], estimate[1], ref)
        bad = xm.logical_not(out.finite) | (
            xm.fabs(out.error_rad) > self.following_error_limit_rad
        )
        self.latched = self.latched | bad
        current = xm.where(self.latched, 0.0, out.current_a)
        self.at_limit_run = xm.where(out.saturated, self.at_limit_run + 1, 0)
        recovering = (
            xm.logical_not(out.bounds_kept)
            | (self.at_limit_run > AT_LIMIT_SAMPLES)
            | (self.recovering_until_ns is not None and stamp < self.recovering_until_ns)
        )
        status = xm.where(
            self.latched,
            int(Status.LATCHED),
            xm.where(recovering, int(Status.RECOVERING), int(Status.OK)),
        )
        if not isinstance(status, (int, np.integer)):
            status = status.astype(int)
        else:
            status = Status(int(status))
        self.commanded = (stamp, current)
        latched = self.latched is True  # a node's scalar latch brakes at once
        self.braking = latched
        return ControlSample(stamp, current, status, t, y, estimate, ref, out, latched)

    def _restart_reference(self, y, shift_s: Optional[float]) -> None:
        """Start the reference from the joint's angle ``y`` (first sample, end of a resync).

        A commanded reference (``restart_from``) holds y. A trajectory is moved by the offset
        y - y_d(shift): ``shift_s`` t_0 after a resync (onto its first rest); None at the first
        sample, where only a controller started away from y_d(0) needs an offset (the paper's
        runs start at 0 = y_d(0)).
        """
        restart_from = getattr(self.reference, 'restart_from', None)
        if restart_from is not None:
            restart_from(y)
            return
        if shift_s is not None:
            self.reference_shift_s = shift_s
            self.reference_offset_rad = y - self.reference.sample(shift_s).position_rad
            return
        offset = y - self.reference.sample(0.0).position_rad
        if xm.any_true(offset != 0.0):
            self.reference_offset_rad = offset

    def _recover_until(self, stamp_ns: int) -> None:
        """Say RECOVERING for RECOVERY_SAMPLES from ``stamp_ns``."""
        self.recovering_until_ns = stamp_ns + RECOVERY_SAMPLES * self.period_ns

    def safe_sample(
        self, stamp_ns: int, status: Status, y=float('nan'), safe_stop: bool = True
    ) -> ControlSample:
        """0 A with ``status`` for sample ``stamp_ns`` (nothing from the law: no stale values).

        Once a command asked for the brake, only the law's next command releases it: a safe
        sample never does (``safe_stop`` is then True whatever was asked).
        """
        self.commanded = (stamp_ns, 0.0)
        safe_stop = safe_stop or self.braking
        self.braking = safe_stop is True
        return ControlSample(stamp_ns, 0.0, status, None, y, None, None, None, safe_stop)

    def stale(
        self, now_ns: int, measurement_timeout_ns: int, estimate_timeout_ns: int
    ) -> Optional[tuple]:
        """(status, age [ns]) of the stalest input older than its timeout, else None.

        Ages on the monotonic clock: ``now_ns`` against the inputs' ``received_ns``.
        """
        if self.start_ns is None or self.latched is True:
            return None
        if self.measurement_received_ns is None:
            return Status.STALE_MEASUREMENT, measurement_timeout_ns + 1
        age = now_ns - self.measurement_received_ns
        if age > measurement_timeout_ns:
            return Status.STALE_MEASUREMENT, age
        if self.needs_estimate:
            if self.estimate_received_ns is None:
                return Status.STALE_ESTIMATE, estimate_timeout_ns + 1
            age = now_ns - self.estimate_received_ns
            if age > estimate_timeout_ns:
                return Status.STALE_ESTIMATE, age
        return None

    def watchdog(
        self, now_ns: int, measurement_timeout_ns: int, estimate_timeout_ns: int
    ) -> Optional[ControlSample]:
        """Return the graded answer to a stale input for the newest measurement, or None.

        Up to the timeout: None (the drive holds the last command); then 0 A without the
        brake; once the input is ``brake_after`` old, 0 A with the brake. The sample is
        answered: its estimate, should it come, is not used any more. A 0 A without the brake
        for a sample already commanded is not to be sent (``command`` False): the joint holds
        that command and would refuse a second one as a replay; the state still says it.
        """
        stale = self.stale(now_ns, measurement_timeout_ns, estimate_timeout_ns)
        if stale is None or self.newest_measurement_ns is None:
            return None
        status, age = stale
        stamp = self.newest_measurement_ns
        y = self.pending[1] if self.pending is not None else float('nan')
        if self.pending is not None and self.pending[0] == stamp:
            self.pending = None
            self.unanswered += 1
        answered = self.commanded is not None and self.commanded[0] == stamp
        sample = self.safe_sample(stamp, status, y, safe_stop=age > self.brake_after_ns)
        self.supervision = _answered(self.supervision, sample.safe_stop)
        if answered and not sample.safe_stop:  # the joint would refuse it as a replay
            return sample._replace(command=False)
        return sample


def _answered(state: Supervision, braked: bool) -> Supervision:
    """Return the supervision after a watchdog answer (``braked``: it asked for the brake).

    A resync in progress stays one; a stall or a brake seen stays (both resync next); else
    the answer braked the joint, or it was a short gap so far.
    """
    if state in (Supervision.RESYNC, Supervision.STALLED, Supervision.BRAKED):
        return state
    return Supervision.BRAKED if braked else Supervision.ANSWERED


def first_rest_s(reference, period_ns: int, horizon_s: float = REST_HORIZON_S) -> float:
    """Return t_0 [s]: the sample nearest rest where the reference's velocity first turns.

    0 when it starts at rest, when it does not turn within ``horizon_s`` (a ramp: restart it
    as it is) or for a batch (velocities an array): a restart there keeps y_d(t - t_r).
    """
    v0 = reference.sample(0.0).velocity_rad_s
    if not _scalar(v0) or v0 == 0.0:
        return 0.0
    dt = period_ns * 1e-9
    before = v0
    for k in range(1, int(round(horizon_s / dt)) + 1):
        v = reference.sample(k * dt).velocity_rad_s
        if v == 0.0 or (v > 0.0) != (v0 > 0.0):  # turned: the sample of the two nearer rest
            return k * dt if abs(v) <= abs(before) else (k - 1) * dt
        before = v
    return 0.0


def input_stamp_refusal(stamp_ns: int, input_ns: Optional[int]) -> str:
    """Why x_hat(k)'s input stamp names no sample at or before k (eq. (15)); '' when it does.

    The pair an estimate integrated is y(k-1), u(k-1): its stamp lies before the estimate's own
    (0 for an initial estimate, which integrated none). Anything else is not the observer's.
    """
    if input_ns is None or 0 <= input_ns <= min(stamp_ns, limits.STAMP_MAX_NS):
        return ''
    return (
        f'estimate for {stamp_ns} ns refused: its input stamp {input_ns} ns is not a sample '
        'at or before it'
    )


def _same(a: tuple, b: tuple) -> bool:
    """Whether two held estimates are the same values (NaN never is)."""
    return a is not CONFLICTED and all(xm.all_true(x == y) for x, y in zip(a, b))


def _scalar(value) -> bool:
    """Tell a node's scalar from a batch of offline runs (an array)."""
    return not isinstance(value, np.ndarray)
