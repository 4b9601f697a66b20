# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The controller's sample assembly at its boundaries: resync length and gap, watchdog, latch.

Each test pins one boundary of ``actuator_core.assembly`` to the sample (49/50 samples of
resync, a gap of gap_limit_samples or one more, a timeout reached or passed), so a limit taken
as < for <=, or a counter not reset, fails here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from actuator_controller.laws import make_controller
from actuator_controller.reference import ReferenceSample, StepReference, make_reference
from actuator_core import limits
from actuator_core.assembly import (
    PENDING_LIMIT,
    RESYNC_MAX_SAMPLES,
    RESYNC_REST_VELOCITY_RAD_S,
    RESYNC_SAMPLES,
    ControlSampleAssembly,
    first_rest_s,
    gap_limit_samples,
)
from actuator_core.status import Status

P = 1_000_000  # 1 ms in ns
#: Samples without a law sample beyond which the assembly resyncs: the command timeout (10 ms).
GAP = gap_limit_samples(P)


def assembly(controller: str = 'pp_nftsmc_eso', **kwargs) -> ControlSampleAssembly:
    """Return an assembly of the paper's fast reference with ``controller``."""
    law = make_controller(controller)
    return ControlSampleAssembly(law, make_reference('fast'), P, controller != 'pi', **kwargs)


def control(a: ControlSampleAssembly, k: int, y: float = 0.0, initial: bool = False):
    """Feed x_hat(k) then y(k); return the sample controlled."""
    a.add_estimate(k * P, 0.0, 0.0, initial=initial)
    return a.add_measurement(k * P, y)


def test_the_documented_constants() -> None:
    """50 samples of resync, a gap of more than the 10 ms command timeout, 64 pending."""
    assert (RESYNC_SAMPLES, GAP, PENDING_LIMIT) == (50, 10, 64)


def test_resync_holds_exactly_resync_samples_then_restarts_from_the_joint() -> None:
    """Samples 0..49 after the restart: 0 A with RESYNC; sample 50: control (RECOVERING), t = 0."""
    a = assembly()
    control(a, 0)
    base = 1000
    statuses = [control(a, base + i, 0.2, initial=i == 0).status for i in range(RESYNC_SAMPLES)]
    assert statuses == [Status.RESYNC] * RESYNC_SAMPLES and a.resyncs == 1
    s = control(a, base + RESYNC_SAMPLES, 0.2)
    assert s.status is Status.RECOVERING and s.t_s == 0.0
    assert s.output.error_rad == pytest.approx(0.0)
    nxt = control(a, base + RESYNC_SAMPLES + 1, 0.2)
    assert nxt.t_s == pytest.approx(1e-3) and a.resyncs == 1


@pytest.mark.parametrize(
    'rest_at, ends_at',
    [
        (None, RESYNC_SAMPLES),  # at rest all along: the 50 samples
        (80, 80),  # still sliding after 50: held until x2_hat is under the rest velocity
        (10_000, RESYNC_MAX_SAMPLES),  # never at rest: restarted after the longest hold anyway
    ],
)
def test_a_resync_holds_on_while_the_braked_joint_still_slides(rest_at, ends_at) -> None:
    """The law restarts once the 50 samples are over and x2_hat is under 0.5 rad/s, at most 300."""
    a = assembly()
    control(a, 0)
    base = 1000
    sliding = 2.0 * RESYNC_REST_VELOCITY_RAD_S
    for i in range(RESYNC_MAX_SAMPLES + 2):
        x2 = 0.0 if rest_at is None or i >= rest_at else sliding
        a.add_estimate((base + i) * P, x2, 0.0, initial=i == 0)
        s = a.add_measurement((base + i) * P, 0.2)
        if s.status is not Status.RESYNC:
            break
    assert i == ends_at and s.status is Status.RECOVERING and s.t_s == 0.0
    assert a.resyncs == 1


@pytest.mark.parametrize('kind', ['fast', 'slow', 'sine'])
def test_a_restart_samples_the_reference_from_its_first_rest(kind) -> None:
    """t_0 is the first sample where the planned velocity turns; the restart starts there, at rest.

    The paper's trajectories start moving (fast: -0.35 rad/s); a braked joint restarted at
    t = 0 would meet a velocity step. A reference at rest at t = 0 (a step) keeps t_0 = 0.
    """
    ref = make_reference(kind)
    t0 = first_rest_s(ref, P)
    k0 = round(t0 * 1e3)
    v = [ref.sample(k * 1e-3).velocity_rad_s for k in range(k0 + 2)]
    assert k0 > 0 and all((x > 0.0) == (v[0] > 0.0) for x in v[: k0 - 1])  # none turned before
    assert (v[k0 - 1] > 0.0) != (v[k0 + 1] > 0.0)  # it turns around t0 ...
    assert abs(v[k0]) <= min(abs(v[k0 - 1]), abs(v[k0 + 1]))  # ... and t0 is the nearer rest
    v_at = v[k0]
    assert first_rest_s(make_reference('step'), P) == 0.0
    a = ControlSampleAssembly(make_controller('pp_nftsmc_eso'), ref, P)
    control(a, 0)
    control(a, 1000, 0.2, initial=True)
    for k in range(1001, 1000 + RESYNC_SAMPLES + 1):
        s = control(a, k, 0.2)
    assert s.status is Status.RECOVERING and s.t_s == 0.0
    assert s.reference.position_rad == pytest.approx(0.2)
    assert s.reference.velocity_rad_s == pytest.approx(v_at)


def test_a_second_restart_during_a_resync_does_not_extend_or_count_it() -> None:
    """An initial estimate while resyncing is the same restart: one resync, same end.

    One at the first sample after the hold is a new restart, counted.
    """
    a = assembly()
    control(a, 0)
    held = control(a, 1000, 0.3, initial=True)
    assert (held.stamp_ns, held.y, held.current_a, held.output) == (1000 * P, 0.3, 0.0, None)
    control(a, 1010, initial=True)
    assert a.resyncs == 1 and a.resync_until_ns == (1000 + RESYNC_SAMPLES) * P
    end = 1000 + RESYNC_SAMPLES
    assert control(a, end, initial=True).status is Status.RESYNC
    assert a.resyncs == 2 and a.resync_until_ns == (end + RESYNC_SAMPLES) * P


def test_a_measurement_gap_resyncs_at_that_stamp_once_its_estimate_comes() -> None:
    """Measurements resume after a long gap: the sample waits for its estimate, then resyncs."""
    a = assembly()
    control(a, 0)
    assert a.add_measurement(150 * P, 0.0) is None  # waits for its estimate
    s = a.add_estimate(150 * P, 0.0, 0.0)
    assert s is not None and s.status is Status.RESYNC and s.stamp_ns == 150 * P
    b = assembly()
    control(b, 0)
    assert b.add_measurement(P, 0.0) is None  # waits for its estimate ...
    assert b.add_estimate(5 * P, 0.0, 0.0, initial=True) is None  # ... a restart far ahead
    assert 'kept aside as a restart' in b.refusal and b.resyncs == 0


def test_a_safe_sample_commands_zero_for_the_correction_of_the_next_estimate() -> None:
    """After a 0 A hold, an estimate that integrated 0 A for that sample is not corrected."""
    a = assembly()
    control(a, 0)
    control(a, 1000, initial=True)
    corrected = a.corrected
    a.add_estimate(1001 * P, 1.0, 2.0, input_ns=1000 * P, input_current_gain=0.5)
    assert a.add_measurement(1001 * P, 0.0).status is Status.RESYNC
    assert a.corrected == corrected
    assert a.commanded == (1001 * P, 0.0)


@pytest.mark.parametrize('gap, resyncs', [(GAP, 0), (GAP + 1, 1)])
def test_a_measurement_gap_resyncs_only_beyond_the_gap_limit(gap: int, resyncs: int) -> None:
    """A measurement GAP samples after the last one is missed samples; GAP + 1 is a resync."""
    a = assembly('pi')
    a.add_measurement(0, 0.0)
    s = a.add_measurement(gap * P, 0.0)
    assert a.resyncs == resyncs and a.missed == gap - 1
    assert s.status is (Status.RESYNC if resyncs else Status.OK)


@pytest.mark.parametrize('gap, resyncs', [(GAP, 0), (GAP + 1, 1)])
def test_an_estimate_gap_resyncs_only_beyond_the_gap_limit(gap: int, resyncs: int) -> None:
    """Measurements go on while estimates stop: the next estimate resyncs after > GAP samples."""
    a = assembly()
    control(a, 0)
    for k in range(1, gap + 1):
        a.add_measurement(k * P, 0.0)
    s = a.add_estimate(gap * P, 0.0, 0.0)
    assert a.resyncs == resyncs and s.status is (Status.RESYNC if resyncs else Status.OK)


@pytest.mark.parametrize('silent_ns, resyncs', [(GAP * P, 0), (GAP * P + 1, 1)])
def test_a_node_silent_beyond_the_command_timeout_resyncs(silent_ns: int, resyncs: int) -> None:
    """No gap in the stamps, but no command sent for longer than the drive's timeout: resync."""
    a = assembly()
    control(a, 0)
    a.command_gap(silent_ns)
    s = control(a, 1)
    assert (a.resyncs, a.gap_resyncs) == (resyncs, resyncs)
    assert s.status is (Status.RESYNC if resyncs else Status.OK)
    assert s.safe_stop is bool(resyncs)


def test_a_stall_the_watchdog_notices_first_holds_the_whole_resync() -> None:
    """The resync of a stall starts at the next law sample, not at the stamp from before it.

    The controller's watchdog timer may run first when the node wakes: the newest stamp it has
    is from before the stall, and a hold counted from there (seen on the running loop: a 60 ms
    stall) was over at once, so the law restarted 1 ms later with no hold and no brake.
    """
    a = assembly()
    for k in range(6):
        control(a, k)
    a.command_gap(60 * P)  # woke after 60 ms: no measurement of after the stall yet

    def measured_then_estimated(k):
        a.add_measurement(k * P, 0.0)
        return a.add_estimate(k * P, 0.0, 0.0)

    held = [measured_then_estimated(60 + i) for i in range(RESYNC_SAMPLES)]
    assert all(s.status is Status.RESYNC and s.safe_stop for s in held)
    restart = measured_then_estimated(60 + RESYNC_SAMPLES)
    assert restart.status is Status.RECOVERING and restart.t_s == 0.0
    assert (a.resyncs, a.gap_resyncs) == (1, 1)


def test_a_stall_that_caught_the_node_mid_sample_holds_from_when_it_woke() -> None:
    """The sample in hand when the stall began resyncs; the hold runs from the wake-up.

    Seen in CI (2026-12-05): the controller, stopped 60 ms with y(k) in hand, resynced at k on
    waking; a hold counted in stamps from k was over at the next sample it took (k + 52 ms),
    so the law restarted on a braked joint at once and drove +20 A for 30 samples.
    """
    a = assembly()
    for k in range(6):  # received 1 ms after their stamps, on the receipt clock
        a.add_estimate(k * P, 0.0, 0.0, received_ns=(k + 1) * P)
        a.add_measurement(k * P, 0.0, received_ns=(k + 1) * P)
    a.add_measurement(6 * P, 0.0, received_ns=7 * P)  # y(6) in hand: the stall begins
    woke = 67 * P
    a.command_gap(60 * P, now_ns=woke)
    s = a.add_estimate(6 * P, 0.0, 0.0, received_ns=woke)
    assert s.status is Status.RESYNC and s.safe_stop

    def sample(k):  # the joint kept its 1 kHz grid; from the wake-up on, 1 ms to the receipt
        a.add_measurement(k * P, 0.0, received_ns=(k + 1) * P)
        return a.add_estimate(k * P, 0.0, 0.0, received_ns=(k + 1) * P)

    held = [sample(k) for k in range(66, 66 + RESYNC_SAMPLES)]  # the newest when it woke: 66
    assert all(h.status is Status.RESYNC and h.safe_stop for h in held), [h.status for h in held]
    restart = sample(66 + RESYNC_SAMPLES)
    assert restart.status is Status.RECOVERING and restart.t_s == 0.0
    assert (a.resyncs, a.gap_resyncs) == (1, 1)


def test_a_silence_the_watchdog_allows_by_design_is_no_stall() -> None:
    """Long stale timeouts (the joint holds its command): silence within them resyncs nothing."""
    a = assembly()
    control(a, 0)
    a.command_gap(50 * P, quiet_ns=75 * P)
    assert control(a, 1).status is not Status.RESYNC and a.resyncs == 0
    a.command_gap(75 * P + 1, quiet_ns=75 * P)
    assert control(a, 2).status is Status.RESYNC and a.gap_resyncs == 1


def test_silence_before_the_first_law_sample_is_no_gap() -> None:
    """A node that never controlled (or is resyncing already) has nothing to resync."""
    a = assembly()
    a.command_gap(10 * GAP * P)
    assert control(a, 0).status is not Status.RESYNC and a.resyncs == 0


def test_missed_and_unanswered_are_counted_exactly() -> None:
    """A jitter of half a period is no missed sample; 3 periods are 2 missed; no estimate: one."""
    a = assembly()
    control(a, 0)
    a.add_measurement(P + P // 2, 0.0)
    assert a.missed == 0 and a.unanswered == 0
    a.add_measurement(4 * P + P // 2, 0.0)
    assert a.missed == 2 and a.unanswered == 1


def test_watchdog_boundaries_and_the_estimate_timeout() -> None:
    """Exactly the timeout old: fine; one ns more: stale. The estimate has its own timeout."""
    a = assembly()
    t0 = 10**6  # samples: the clock is far from zero, as in real time
    control(a, t0)
    now = t0 * P
    assert a.watchdog(now + 3 * P, 5 * P, 3 * P) is None
    assert a.watchdog(now + 3 * P + 1, 5 * P, 3 * P).status is Status.STALE_ESTIMATE
    assert a.watchdog(now + 5 * P, 5 * P, 10 * P) is None
    assert a.watchdog(now + 5 * P + 1, 5 * P, 10 * P).status is Status.STALE_MEASUREMENT
    a.add_measurement(now + 5 * P, 0.0)
    assert a.watchdog(now + 5 * P, 5 * P, 10 * P) is None
    pi = assembly('pi')
    pi.add_measurement(now, 0.0)
    assert pi.watchdog(now + 4 * P, 5 * P, 1) is None  # PI waits for no estimate


def test_a_brake_a_safe_stop_engaged_stays_until_the_law_commands_again() -> None:
    """A stale answer within brake_after asks no brake after a law sample, but keeps a resync's.

    Seen in the real-time restart test: the watchdog's 'no brake yet' answer, for a sample of a
    resync episode, released the brake the resync had engaged.
    """
    a = assembly()
    control(a, 0)
    coast = a.watchdog(6 * P + 1, 10 * P, 5 * P)  # stale, younger than brake_after
    assert coast.status is Status.STALE_ESTIMATE and coast.safe_stop is False
    held = control(a, 1000, 0.2, initial=True)  # the observer restarted: resync, brake
    assert held.status is Status.RESYNC and held.safe_stop is True
    a.add_measurement(1001 * P, 0.2)
    still = a.watchdog(1001 * P + 5 * P + 1, 10 * P, 5 * P)
    assert still.status is Status.STALE_ESTIMATE and still.safe_stop is True
    refused = a.safe_sample(1002 * P, Status.INVALID_INPUT, 0.2, safe_stop=False)
    assert refused.safe_stop is True
    for k in range(1002, 1000 + RESYNC_SAMPLES + 1):
        last = control(a, k, 0.2)
    assert last.status is Status.RECOVERING and last.safe_stop is False  # the law released it
    a.add_measurement((1000 + RESYNC_SAMPLES + 1) * P, 0.2)
    again = a.watchdog((1000 + RESYNC_SAMPLES + 1) * P + 5 * P + 1, 10 * P, 5 * P)
    assert again.safe_stop is False  # graded again: 0 A without the brake first


@pytest.mark.parametrize('age_ns, resyncs', [(10 * P, 0), (10 * P + 1, 1)])
def test_a_watchdog_brake_resyncs_even_when_the_next_stamps_show_no_gap(age_ns, resyncs) -> None:
    """The watchdog braked the joint: its next law sample takes the resync path, not the chase.

    A stalled joint replays its samples and sends them at once: the stamps the law then runs on
    are contiguous, yet the joint stood braked meanwhile. A 0 A answer without the brake (the
    input exactly brake_after old) keeps the law going, saying RECOVERING.
    """
    a = assembly()
    control(a, 0)
    answer = a.watchdog(age_ns, 7 * P, 7 * P)
    assert answer.safe_stop is bool(resyncs)
    s = control(a, 1)
    assert (a.resyncs, a.gap_resyncs) == (resyncs, resyncs)
    assert s.status is (Status.RESYNC if resyncs else Status.RECOVERING)
    assert s.safe_stop is bool(resyncs)
    if resyncs:  # once resynced, the brake answer is spent: no second resync after the hold
        for k in range(2, 1 + RESYNC_SAMPLES + 2):
            s = control(a, k)
        assert s.status is Status.RECOVERING and a.resyncs == 1


def test_latched_assembly_has_no_watchdog_and_reset_clears_the_latch() -> None:
    """Latched: the watchdog is silent; reset: a new start that controls again."""
    a = assembly(following_error_limit_rad=0.1)
    control(a, 0)
    assert control(a, 1, 0.1 + 1e-9).status is Status.LATCHED
    assert a.watchdog(10**12, P, P) is None
    a.reset()
    assert not a.latched and a.start_ns is None and a.resyncs == 0
    s = control(a, 2, 0.05)
    assert s.status is Status.OK and s.t_s == 0.0


def test_following_error_limit_is_inclusive() -> None:
    """|e| equal to the limit keeps control; the latch needs more."""
    probe = assembly('pi')
    probe.add_measurement(0, 0.0)
    error = probe.add_measurement(P, 0.0).output.error_rad
    assert error != 0.0
    for limit, status in (
        (abs(error), Status.OK),
        (np.nextafter(abs(error), 0.0), Status.LATCHED),
    ):
        a = assembly('pi', following_error_limit_rad=limit)
        a.add_measurement(0, 0.0)
        assert a.add_measurement(P, 0.0).status is status, limit


def test_correction_only_for_the_pair_of_the_last_command() -> None:
    """The estimate is corrected when it integrated another current for the last command."""
    a = assembly()
    a.add_estimate(0, 0.0, 0.0)
    commanded = a.add_measurement(0, 0.0).current_a
    a.add_estimate(P, 1.0, 2.0, input_ns=0, input_current_a=commanded, input_current_gain=0.5)
    assert a.add_measurement(P, 0.0).estimate == (1.0, 2.0) and a.corrected == 0
    a.add_estimate(
        2 * P, 1.0, 2.0, input_ns=0, input_current_a=commanded + 1, input_current_gain=0.5
    )
    assert a.add_measurement(2 * P, 0.0).estimate == (1.0, 2.0)  # not the last command's pair
    assert a.corrected == 0


def test_an_estimate_naming_no_input_is_never_corrected() -> None:
    """Without its input stamp, x_hat is taken as it is, even after a command at stamp 0."""
    a = assembly()
    a.add_estimate(0, 0.0, 0.0)
    assert a.add_measurement(0, 0.1).current_a != 0.0  # commanded for stamp 0
    a.add_estimate(P, 1.0, 2.0, input_current_gain=0.5)
    assert a.add_measurement(P, 0.1).estimate == (1.0, 2.0) and a.corrected == 0


def test_an_estimate_naming_its_input_but_no_gain_keeps_its_x2() -> None:
    """The current's gain in x2_hat defaults to 0: another current integrated moves nothing."""
    a = assembly()
    a.add_estimate(0, 0.0, 0.0)
    commanded = a.add_measurement(0, 0.1).current_a
    a.add_estimate(P, 1.0, 2.0, input_ns=0, input_current_a=commanded + 1.0)
    assert a.add_measurement(P, 0.1).estimate == (1.0, 2.0)


def test_estimates_beyond_the_next_sample_are_refused() -> None:
    """x_hat(k+1) exists before y(k+1); one further ahead answers no measurement seen."""
    a = assembly()
    control(a, 0)
    assert a.add_estimate(P, 0.0, 0.0) is None and a.refusal == ''  # the next sample: kept
    assert a.add_estimate(2 * P, 0.0, 0.0) is None and a.refusal  # beyond it: refused
    assert a.refused == 1 and 2 * P not in a.estimates
    assert a.add_measurement(P, 0.0).status is Status.OK


def test_a_batch_latches_element_by_element() -> None:
    """Arrays: the run with the large error latches alone; the other keeps its command."""
    a = assembly(following_error_limit_rad=0.1)
    y = np.array([0.0, 0.0])
    a.add_estimate(0, np.zeros(2), np.zeros(2))
    first = a.add_measurement(0, y)
    assert list(first.status) == [Status.OK, Status.OK]
    a.add_estimate(P, np.zeros(2), np.zeros(2))
    s = a.add_measurement(P, np.array([0.0, 0.5]))
    assert list(s.status) == [int(Status.OK), int(Status.LATCHED)] and s.current_a[1] == 0.0
    assert np.isfinite(s.current_a[0]) and s.current_a[0] != 0.0


def test_reset_keeps_the_configuration() -> None:
    """Cleanup and configure start over with the same period, law inputs, limit and resync."""
    law = make_controller('pi')
    a = ControlSampleAssembly(
        law, make_reference('fast'), 2 * P, False, following_error_limit_rad=0.01, resync_samples=7
    )
    a.add_measurement(0, 0.0)
    a.reset()
    assert (a.period_ns, a.needs_estimate, a.following_error_limit_rad, a.resync_samples) == (
        2 * P,
        False,
        0.01,
        7,
    )
    assert a.law is law and a.add_measurement(0, 0.0).status is Status.OK


def test_reset_keeps_the_brake_delay() -> None:
    """brake_after 30 ms (the default is 10 ms) holds after reset: 20 ms stale is 0 A, no brake."""
    a = assembly('pi', brake_after_s=0.03)
    a.add_measurement(0, 0.0)
    a.reset()
    a.add_measurement(0, 0.0)
    coast = a.watchdog(20 * P, 5 * P, 5 * P)
    assert coast.status is Status.STALE_MEASUREMENT and coast.safe_stop is False
    assert a.watchdog(30 * P + 1, 5 * P, 5 * P).safe_stop is True


def test_every_corrected_estimate_is_counted() -> None:
    """Two estimates integrated with a substitute: two corrections."""
    a = assembly()
    for k in range(2):
        a.add_estimate(k * P, 0.0, 0.0, input_ns=max(k - 1, 0) * P)
        commanded = a.add_measurement(k * P, 0.0).current_a
    before = a.corrected
    for k in (2, 3):
        a.add_estimate(
            k * P, 0.0, 0.0, input_ns=(k - 1) * P, input_current_a=commanded + 1.0,
            input_current_gain=0.1,
        )  # fmt: skip
        commanded = a.add_measurement(k * P, 0.0).current_a
    assert a.corrected == before + 2


def test_a_resync_keeps_the_estimate_already_in_for_its_own_stamp() -> None:
    """The node resyncs at y(k)'s stamp (its time base jumped) after x_hat(k) came: k is held.

    x_hat(k) is made before y(k) exists; dropping it with the older ones would leave y(k)
    waiting for an estimate that never comes again.
    """
    a = assembly()
    control(a, 0)
    a.add_estimate(P, 0.0, 0.0)
    a.resync(P)
    s = a.add_measurement(P, 0.1)
    assert s is not None and (s.stamp_ns, s.status, s.y, s.safe_stop) == (
        P,
        Status.RESYNC,
        0.1,
        True,
    )


def test_a_restart_for_the_next_sample_forgets_the_measurement_waiting_before_it() -> None:
    """y(1) waits for x_hat(1); the observer restarts at sample 2: y(1) is dropped, 2 is held."""
    a = assembly()
    control(a, 0)
    assert a.add_measurement(P, 0.1) is None  # waits for its estimate
    assert a.add_estimate(2 * P, 0.0, 0.0, initial=True) is None  # resync from sample 2
    assert a.resyncs == 1 and a.add_estimate(P, 0.0, 0.0) is None  # y(1) is not controlled
    s = a.add_measurement(2 * P, 0.2)
    assert (s.stamp_ns, s.status, s.y) == (2 * P, Status.RESYNC, 0.2)


def test_the_watchdog_answers_the_waiting_measurement_with_its_angle_and_counts_it() -> None:
    """A stale estimate: the watchdog answers y(k) waiting for it (its y, counted unanswered).

    With nothing waiting its answer has no angle (NaN). Each answered sample counts one.
    """
    a = assembly()
    control(a, 0)
    a.add_measurement(P, 0.1)
    a.add_measurement(2 * P, 0.25)  # y(1) is superseded unanswered
    assert a.unanswered == 1
    s = a.watchdog(6 * P + 1, 10 * P, 6 * P)  # x_hat(0) is 6 ms + 1 ns old
    assert (s.stamp_ns, s.status, s.y, s.current_a) == (2 * P, Status.STALE_ESTIMATE, 0.25, 0.0)
    assert a.unanswered == 2
    again = a.watchdog(6 * P + 2, 10 * P, 6 * P)  # the same sample, nothing waits any more
    assert again.stamp_ns == 2 * P and math.isnan(again.y) and a.unanswered == 2
    assert a.add_estimate(2 * P, 0.0, 0.0) is None  # answered: its estimate is not used


def test_the_same_estimate_twice_is_no_conflict_but_nan_is_never_the_same() -> None:
    """A repeated estimate (same values) is used; a NaN one repeated is two claims: 0 A."""
    a = assembly()
    control(a, 0)
    a.add_estimate(P, 0.1, 0.2)
    assert a.add_estimate(P, 0.1, 0.2) is None and a.refusal == '' and a.conflicts == 0
    s = a.add_measurement(P, 0.0)
    assert s.estimate == (0.1, 0.2) and s.output is not None
    a.add_estimate(2 * P, float('nan'), 0.2)
    a.add_estimate(2 * P, float('nan'), 0.2)
    assert a.conflicts == 1
    s = a.add_measurement(2 * P, 0.0)
    assert (s.status, s.current_a, s.output) == (Status.INVALID_INPUT, 0.0, None)


@pytest.mark.parametrize(
    'period_ns, samples',
    [(P, 10), (4 * P, 2), (800_000, 12), (20 * P, 1), (200 * P, 1)],
)
def test_the_gap_limit_is_the_command_timeout_in_whole_samples(period_ns, samples) -> None:
    """10 ms over the period, to the nearest sample (a tie to the even count, as round() does).

    At least one sample: a period longer than the timeout still needs a gap to resync.
    """
    assert gap_limit_samples(period_ns) == samples


def test_a_brake_delay_of_one_second_counts_to_the_nanosecond() -> None:
    """brake_after 1 s: an input exactly 1 s old coasts at 0 A; 1 ns older brakes."""
    a = assembly('pi', brake_after_s=1.0)
    a.add_measurement(0, 0.0)
    assert a.watchdog(10**9, P, P).safe_stop is False
    assert a.watchdog(10**9 + 1, P, P).safe_stop is True


def test_a_fresh_assembly_has_refused_nothing_and_corrects_nothing() -> None:
    """No refusal yet; this node has commanded nothing, so any pair an estimate names is kept."""
    a = assembly()
    assert a.refusal == ''
    a.add_estimate(2, 1.0, 2.0, input_ns=1, input_current_a=3.0, input_current_gain=0.5)
    s = a.add_measurement(2, 0.0)
    assert s.estimate == (1.0, 2.0) and a.corrected == 0 and a.refusal == ''


def test_a_refused_first_estimate_answers_0_a_without_the_brake() -> None:
    """x2_hat beyond the velocity limit at the first sample: INVALID_INPUT, 0 A, no brake asked."""
    a = assembly()
    a.add_estimate(0, limits.VELOCITY_LIMIT_RAD_S + 1.0, 0.0)
    s = a.add_measurement(0, 0.0)
    assert (s.status, s.current_a, s.safe_stop) == (Status.INVALID_INPUT, 0.0, False)
    assert a.braking is False


def test_a_restart_ahead_of_the_measurements_says_both_why_and_that_it_is_kept() -> None:
    """The refusal (how far ahead) and the note that the restart is kept aside, in one text."""
    a = assembly()
    control(a, 0)
    a.add_measurement(P, 0.0)
    assert a.add_estimate(5 * P, 0.0, 0.0, initial=True) is None
    assert a.refusal == (
        f'estimate stamped {5 * P} ns refused: 4 ms ahead of the newest measurement seen '
        '(at most 1 sample); kept aside as a restart, used if that measurement comes'
    )


def test_every_conflicted_estimate_sample_is_counted() -> None:
    """Two samples each claimed by two different estimates: two conflicts, each 0 A."""
    a = assembly()
    control(a, 0)
    for k in (1, 2):
        a.add_estimate(k * P, 0.1, 0.0)
        a.add_estimate(k * P, 0.2, 0.0)
        s = a.add_measurement(k * P, 0.0)
        assert (s.status, s.current_a) == (Status.INVALID_INPUT, 0.0)
    assert a.conflicts == 2


def test_the_estimate_age_counts_from_the_newest_sample_received_on_the_monotonic_clock() -> None:
    """Ages use received_ns, not the stamp; a repeat of the newest refreshes it, an older not."""
    a = assembly()
    t0 = 10**12  # the receiver's monotonic clock, far from the stamps
    a.add_estimate(0, 0.0, 0.0, received_ns=t0)
    a.add_measurement(0, 0.0, received_ns=t0)
    a.add_measurement(P, 0.0, received_ns=t0 + P)
    a.add_estimate(P, 0.0, 0.0, received_ns=t0 + P)
    assert a.watchdog(t0 + 6 * P, 10 * P, 5 * P) is None  # 5 ms old: not stale yet
    a.add_estimate(P, 0.0, 0.0, received_ns=t0 + 4 * P)  # the newest again: alive
    assert a.watchdog(t0 + 9 * P, 10 * P, 5 * P) is None
    a.add_estimate(0, 0.0, 0.0, received_ns=t0 + 8 * P)  # an older sample: no sign of life
    stale = a.watchdog(t0 + 9 * P + 1, 10 * P, 5 * P)
    assert stale.status is Status.STALE_ESTIMATE


def test_estimates_waiting_for_their_measurements_keep_the_newest_pending_limit() -> None:
    """y(100) waits; 70 estimates of earlier samples come: the newest PENDING_LIMIT are kept."""
    a = assembly()
    a.add_measurement(100 * P, 0.0)
    for k in range(70):
        assert a.add_estimate(k * P, 0.0, 0.0) is None
    assert len(a.estimates) == PENDING_LIMIT and min(a.estimates) == (70 - PENDING_LIMIT) * P
    assert a.add_estimate(100 * P, 0.0, 0.0).stamp_ns == 100 * P
    assert not a.estimates  # the older ones go with the sample controlled


def test_missed_samples_are_whole_samples_between_measurements() -> None:
    """Early by half a period: none missed (never fewer); 2 periods: 1; 3.5 periods: 2.

    Far from stamp 0 (as in real time) and each gap added to the count before.
    """
    a = assembly('pi')
    t = 1000 * P
    for gap in (0, P // 2, 2 * P, 3 * P + P // 2, 3 * P // 2):
        t += gap
        a.add_measurement(t, 0.0)
    assert a.missed == 3 and isinstance(a.missed, int)


def test_a_kept_aside_restart_keeps_its_receipt_time() -> None:
    """A restart kept aside until its y came is as old as its receipt at monotonic t_r."""
    a = assembly()
    t0 = 10**12
    a.add_estimate(0, 0.0, 0.0, received_ns=t0)
    a.add_measurement(0, 0.0, received_ns=t0)
    a.add_estimate(3 * P, 0.0, 0.0, initial=True, received_ns=t0 + P)  # kept aside
    s = a.add_measurement(3 * P, 0.0, received_ns=t0 + 3 * P)
    assert s.status is Status.RESYNC and a.resyncs == 1
    assert a.watchdog(t0 + 6 * P, 10 * P, 5 * P) is None  # estimate 5 ms old
    assert a.watchdog(t0 + 6 * P + 1, 10 * P, 5 * P).status is Status.STALE_ESTIMATE


def test_pi_runs_with_no_estimate_and_reports_none_used() -> None:
    """PI takes no estimate: the sample carries (0, 0) as the estimate used."""
    a = assembly('pi')
    s = a.add_measurement(0, 0.0)
    assert s.estimate == (0.0, 0.0) and s.status is Status.OK


@pytest.mark.parametrize('x2, refused', [(limits.VELOCITY_LIMIT_RAD_S, 0), (-20.0000001, 1)])
def test_the_estimate_velocity_limit_is_inclusive(x2, refused) -> None:
    """x2_hat of exactly the velocity limit is used; beyond it the sample gets 0 A, no brake."""
    a = assembly()
    control(a, 0)
    a.add_estimate(P, x2, 0.5)
    s = a.add_measurement(P, 0.125)
    assert a.refused == refused
    if refused:
        assert (s.stamp_ns, s.status, s.current_a, s.y) == (P, Status.INVALID_INPUT, 0.0, 0.125)
        assert s.safe_stop is False and s.output is None
        assert a.refusal == (
            f'estimate for {P} ns refused: x2_hat corrected for the current commanded is '
            '-20 rad/s, beyond +-20'
        )
        a.add_estimate(2 * P, x2, 0.5)
        a.add_measurement(2 * P, 0.125)
        assert a.refused == 2  # each refusal counted
    else:
        assert s.output is not None and s.estimate == (x2, 0.5)


def test_a_conflicted_sample_answers_its_own_stamp_and_angle_without_the_brake() -> None:
    """The 0 A answer to two different estimates names the sample and its y; no brake asked."""
    a = assembly()
    control(a, 0)
    a.add_estimate(P, 0.1, 0.0)
    a.add_estimate(P, 0.2, 0.0)
    s = a.add_measurement(P, 0.0625)
    assert (s.stamp_ns, s.y, s.status) == (P, 0.0625, Status.INVALID_INPUT)
    assert s.safe_stop is False


def test_a_latched_sample_names_its_stamp_and_angle() -> None:
    """Once latched, every sample is 0 A with the brake, for its own stamp and measured y."""
    a = assembly(following_error_limit_rad=0.1)
    control(a, 0)
    control(a, 1, 0.2)
    s = control(a, 2, 0.0625)
    assert (s.stamp_ns, s.status, s.current_a, s.y, s.safe_stop) == (
        2 * P,
        Status.LATCHED,
        0.0,
        0.0625,
        True,
    )


def test_every_gap_resync_is_counted() -> None:
    """Two gaps beyond the limit, each after control resumed: two gap resyncs."""
    a = assembly('pi')
    a.add_measurement(0, 0.0)
    a.add_measurement((GAP + 1) * P, 0.0)
    k = GAP + 1 + RESYNC_SAMPLES
    assert a.add_measurement(k * P, 0.0).status is Status.RECOVERING
    a.add_measurement((k + GAP + 1) * P, 0.0)
    assert a.gap_resyncs == 2 and a.resyncs == 2


@pytest.mark.parametrize('y', [1.5, 0.25])
def test_a_reference_is_started_from_the_joint_angle_where_it_does_not_start(y) -> None:
    """A step of 0.5 rad at t = 0 and the joint at y: the first sample's error is 0.

    The reference is shifted by y - y_d(0) (1 rad: beyond the following-error limit otherwise).
    """
    a = ControlSampleAssembly(make_controller('pi'), StepReference(0.5), P, False)
    s = a.add_measurement(0, y)
    assert s.status is Status.OK and s.output.error_rad == 0.0
    assert s.reference.position_rad == y


def test_a_controlled_sample_carries_its_y_and_a_batch_its_statuses_as_ints() -> None:
    """The law's sample names the y it ran on; a batch's statuses are an int array."""
    a = assembly()
    a.add_estimate(0, 0.0, 0.0)
    assert a.add_measurement(0, 0.0).y == 0.0
    a.add_estimate(P, 0.0, 0.0)
    assert a.add_measurement(P, 0.015625).y == 0.015625
    batch = assembly()
    batch.add_estimate(0, np.zeros(2), np.zeros(2))
    s = batch.add_measurement(0, np.zeros(2))
    assert s.status.dtype.kind == 'i' and list(s.status) == [Status.OK, Status.OK]


class _Velocities:
    """A reference whose velocity at sample k (1 ms) is ``v[k]`` (the last one after them)."""

    def __init__(self, *v):
        self.v = v

    def sample(self, t):
        k = min(round(t * 1e3), len(self.v) - 1)
        return ReferenceSample(0.0, self.v[k], 0.0)


@pytest.mark.parametrize(
    'velocities, horizon_s, rest_s',
    [
        ((3.0, 2.0, 1.0, 0.0, -1.0), 1.0, 3e-3),  # at rest at sample 3
        ((0.5, 0.4, 0.3, 0.2, 0.1, 0.0), 1.0, 5e-3),  # a slow positive start
        ((1.0, -0.5), 1.0, 1e-3),  # turned at once, sample 1 nearer rest
        ((1.0, -2.0), 1.0, 0.0),  # turned at once, sample 0 nearer rest
        ((1.0, -1.0), 1.0, 1e-3),  # a tie: the sample after the turn
        ((1.0, 0.5, -2.0), 1.0, 1e-3),  # turned at sample 2, sample 1 nearer rest
        ((0.3,) * 9 + (0.2, -0.1), 0.01, 10e-3),  # turns at the horizon's last sample
        ((0.3,) * 10 + (0.2, -0.1), 0.01, 0.0),  # one sample beyond it: restart as it is
    ],
)
def test_first_rest_is_the_sample_nearer_rest_where_the_velocity_first_turns(
    velocities, horizon_s, rest_s
) -> None:
    """Sample by sample from t = dt up to the horizon; 0 when it does not turn within it."""
    assert first_rest_s(_Velocities(*velocities), P, horizon_s) == rest_s


def test_first_rest_of_a_batch_is_0() -> None:
    """Velocities an array (a batch of runs): no common rest; the restart keeps y_d(t - t_r)."""

    class Batch:
        def sample(self, t):
            return ReferenceSample(np.zeros(2), np.array([-0.35, 0.2]) * (1.0 - t), np.zeros(2))

    assert first_rest_s(Batch(), P) == 0.0


def test_an_estimate_whose_input_stamp_is_no_sample_before_it_is_refused() -> None:
    """input_stamp names the pair x_hat(k) integrated: a negative one or one after k is not it.

    A sentinel-looking stamp with a current (-1 ns, 5 A) never reaches the correction: it is
    refused with its reason before, and the estimate is not used.
    """
    a = assembly()
    control(a, 0)
    for bad in (-1, 2 * P, limits.STAMP_MAX_NS + 1):
        assert a.add_estimate(P, 0.0, 0.0, input_ns=bad, input_current_a=5.0) is None
        assert a.refusal == (
            f'estimate for {P} ns refused: its input stamp {bad} ns is not a sample at or '
            'before it'
        )
    assert a.refused == 3 and P not in a.estimates
    assert a.add_estimate(P, 0.0, 0.0, input_ns=0, input_current_a=5.0) is None  # waits for y
    assert a.refusal == '' and P in a.estimates


def test_the_watchdog_sends_no_second_command_for_a_sample_the_joint_already_holds() -> None:
    """A stale measurement after sample 0 was commanded: the 0 A answer is the state's only.

    The joint takes one command per sample, and a safe stop in any one's place: a 0 A without
    the brake for sample 0 would be refused as a replay (an ERROR at the end of every run). An
    unanswered sample still gets its 0 A, and the brake grade always goes out.
    """
    a = assembly()
    control(a, 0)  # the law commanded sample 0
    s = a.watchdog(8 * P, 7 * P, 7 * P)
    assert (s.status, s.stamp_ns, s.safe_stop, s.command) == (
        Status.STALE_MEASUREMENT,
        0,
        False,
        False,
    )
    s = a.watchdog(11 * P, 7 * P, 7 * P)  # past BRAKE_AFTER_S: the safe stop is sent
    assert (s.stamp_ns, s.safe_stop, s.command) == (0, True, True)
    b = assembly()
    control(b, 0)
    b.add_measurement(P, 0.0, received_ns=8 * P)  # y(1) came late, its estimate never does
    s = b.watchdog(9 * P, 7 * P, 7 * P)
    assert (s.status, s.stamp_ns, s.safe_stop, s.command) == (
        Status.STALE_ESTIMATE,
        P,
        False,
        True,
    )


def test_the_state_is_never_ok_while_the_command_sits_at_the_limit_past_a_handful() -> None:
    """AT_LIMIT_SAMPLES at the limit may say OK (a step); the next says RECOVERING until off it."""
    from actuator_core.assembly import AT_LIMIT_SAMPLES

    step = StepReference(amplitude_rad=1.0, start_s=0.001)
    a = ControlSampleAssembly(
        make_controller('pi'), step, P, False, following_error_limit_rad=10.0
    )
    assert a.add_measurement(0, 0.0).status is Status.OK  # on the reference before its step
    statuses = []
    for k in range(1, AT_LIMIT_SAMPLES + 4):  # the joint does not follow the step: +20 A
        s = a.add_measurement(k * P, 0.0)
        assert s.current_a == 20.0
        statuses.append(s.status)
    assert statuses[:AT_LIMIT_SAMPLES] == [Status.OK] * AT_LIMIT_SAMPLES
    assert statuses[AT_LIMIT_SAMPLES:] == [Status.RECOVERING] * 3
    s = a.add_measurement((AT_LIMIT_SAMPLES + 4) * P, 1.0)  # the joint on the reference again
    assert abs(s.current_a) < 20.0 and s.status is Status.OK and a.at_limit_run == 0
