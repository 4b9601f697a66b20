# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The sample protocol without processes.

Observer pairing, controller sample assembly, drive gate.
"""

import math

import numpy as np
import pytest

from actuator_controller.laws import make_controller
from actuator_controller.reference import make_reference
from actuator_core import limits
from actuator_core.assembly import (
    AT_LIMIT_SAMPLES,
    RECOVERY_SAMPLES,
    RESYNC_SAMPLES,
    ControlSampleAssembly,
)
from actuator_core.gate import CommandGate
from actuator_core.pairing import MAX_STEPS_PER_CALL, ObserverInputPairing
from actuator_core.status import Status
from actuator_core.timebase import StampCheck, Verdict
from actuator_eso.observer import EsoGains, ExtendedStateObserver, eso_step

P = 1_000_000  # 1 ms in ns


def pairing(patience=1):
    eso = ExtendedStateObserver(EsoGains(), 1e-3)
    return ObserverInputPairing(eso, P, eso.correction, patience), eso


def test_pairing_steps_only_on_the_pair_of_the_same_stamp_in_either_order():
    pair, eso = pairing()
    first = pair.add_measurement(0, 0.0)
    assert len(first) == 1 and first[0].initial and first[0].sample_ns == 0
    assert pair.add_command(0, 2.0)[0].sample_ns == P  # y(0) then u(0): x_hat(1)
    assert pair.add_command(P, 3.0) == []  # u(1) before y(1): waits
    out = pair.add_measurement(P, 0.01)
    assert [e.sample_ns for e in out] == [2 * P] and not out[0].substituted
    expected = eso_step(
        *eso_step(0.0, 0.0, 0.0, 0.0, 2.0, 1e-3, EsoGains()), 0.01, 3.0, 1e-3, EsoGains()
    )
    assert out[0].x_hat == expected  # exactly the two Euler steps of (15)


def test_pairing_substitutes_a_missing_command_and_repairs_it_exactly_when_it_comes():
    pair, eso = pairing()
    pair.add_measurement(0, 0.0)
    pair.add_command(0, 1.0)
    pair.add_measurement(P, 0.0)
    out = pair.add_measurement(2 * P, 0.0)  # u(1) never came in time
    assert len(out) == 1 and out[0].substituted and out[0].input_current_a == 1.0
    pair.add_command(P, 5.0)  # ... and now it does
    assert pair.repaired == 1
    exact, _ = pairing()
    exact.add_measurement(0, 0.0)
    exact.add_command(0, 1.0)
    exact.add_measurement(P, 0.0)
    exact.add_command(P, 5.0)
    assert exact.observer.state == pytest.approx(eso.state, rel=1e-12, abs=1e-15)


def test_pairing_keeps_a_command_that_comes_before_the_first_measurement():
    pair, _ = pairing()
    assert pair.add_command(0, 2.0) == []
    out = pair.add_measurement(0, 0.0)
    assert [e.initial for e in out] == [True, False] and out[1].input_current_a == 2.0


def test_pairing_ignores_duplicates_and_stale_samples_and_bounds_its_work():
    pair, _ = pairing(patience=1000)
    pair.add_measurement(0, 0.0)
    pair.add_command(0, 0.0)
    assert pair.add_measurement(P, 0.0) == [] and pair.add_measurement(P, 0.5) == []  # duplicate
    assert pair.add_measurement(0, 0.0) == []  # older than x_hat
    assert pair.ignored == 2
    for k in range(2, 60):
        pair.add_measurement(k * P, 0.0)
    for k in range(2, 60):
        pair.add_command(k * P, 0.0)
    out = pair.add_command(P, 0.0)  # frees 59 samples: at most MAX per call
    assert len(out) == MAX_STEPS_PER_CALL


def test_pairing_restart_starts_the_observer_from_the_measurement():
    pair, eso = pairing()
    pair.add_measurement(0, 0.0)
    pair.add_command(0, 1.0)
    (out,) = pair.restart(10**12, 0.7)
    assert (
        out.initial
        and out.sample_ns == 10**12
        and eso.state == (0.7, 0.0, 0.0)
        and pair.restarts == 1
    )
    assert pair.add_command(10**12 + 10**9, 1.0) == []  # a command far ahead of x_hat: ignored
    assert pair.add_command(10**12, 1.0)[0].sample_ns == 10**12 + P


def test_stamp_check_sorts_future_old_and_jumps_in_real_time():
    c = StampCheck(P, sim=False, future_tolerance_ns=50 * P)
    now = 10**12
    assert c.check(now, now) is Verdict.OK
    assert c.check(now + 1000 * 10**9, now) is Verdict.FUTURE  # 1000 s ahead: refused
    assert c.check(now + 3 * P, now + 3 * P) is Verdict.OK  # two missed samples: fine
    assert c.check(now + 2 * P, now + 3 * P) is Verdict.OLD  # late or duplicate
    assert c.check(now + 3 * P + 1234, now + 4 * P) is Verdict.JUMP  # a new grid: restarted sensor
    assert (
        c.check(now + 4 * P + 1234, now + 5 * P) is Verdict.OK
    )  # ... which is the grid from now on
    assert c.check(now - 10**10, now + 5 * P) is Verdict.JUMP  # 10 s back
    assert (c.refused_future, c.ignored_old, c.jumps) == (1, 1, 2)


def test_stamp_check_in_sim_allows_only_the_next_sample_and_treats_any_step_back_as_a_restart():
    c = StampCheck(P, sim=True, future_tolerance_ns=0)
    assert c.check(10**9, 0) is Verdict.OK
    assert c.check(10**9 + P, 0) is Verdict.OK
    assert c.check(10**9 + 3 * P, 0) is Verdict.FUTURE
    assert c.check(10**9, 0) is Verdict.JUMP  # a restarted plant starts again


def assembly(controller='pp_nftsmc_eso', **kwargs):
    law = make_controller(controller)
    return ControlSampleAssembly(law, make_reference('fast'), P, controller != 'pi', **kwargs)


def test_assembly_controls_a_sample_once_both_halves_are_in():
    a = assembly()
    assert a.add_measurement(0, 0.0) is None
    s = a.add_estimate(0, 0.0, 0.0)
    assert s.stamp_ns == 0 and s.status is Status.OK and math.isfinite(s.current_a)
    assert a.add_estimate(P, 0.0, 0.0) is None  # estimate first, then its measurement
    assert a.add_measurement(P, 1e-4).stamp_ns == P
    pi = assembly('pi')
    assert pi.add_measurement(0, 0.0).status is Status.OK  # PI needs no estimate


def test_assembly_corrects_an_estimate_integrated_with_a_substituted_current():
    a = assembly()
    a.add_estimate(0, 0.0, 0.0)
    commanded = a.add_measurement(0, 0.0).current_a
    a.add_estimate(
        P, 0.5, 1.0, input_ns=0, input_current_a=commanded + 2.0, input_current_gain=0.03
    )
    s = a.add_measurement(P, 0.0)
    assert s.estimate == pytest.approx((0.5 - 2.0 * 0.03, 1.0)) and a.corrected == 1


def test_assembly_counts_unanswered_and_missed_samples():
    a = assembly()
    a.add_measurement(0, 0.0)
    a.add_measurement(P, 0.0)  # y(0) never got its estimate
    a.add_measurement(4 * P, 0.0)  # samples 2 and 3 never came
    assert a.unanswered == 2 and a.missed == 2


def test_assembly_latches_on_following_error_and_on_non_finite_output():
    a = assembly(following_error_limit_rad=0.1)
    a.add_estimate(0, 0.0, 0.0)
    assert a.add_measurement(0, 0.0).status is Status.OK
    a.add_estimate(P, 0.0, 0.0)
    latched = a.add_measurement(P, 0.2)
    assert latched.status is Status.LATCHED and latched.safe_stop
    a.add_estimate(2 * P, 0.0, 0.0)
    later = a.add_measurement(2 * P, 0.0)
    assert later.status is Status.LATCHED and later.current_a == 0.0 and later.output is None
    b = assembly()
    b.add_estimate(0, float('inf'), 0.0)
    s = b.add_measurement(0, 0.0)
    assert s.status is Status.LATCHED and s.current_a == 0.0


def test_assembly_watchdog_answers_stale_inputs_in_grades():
    a = assembly()
    assert a.watchdog(10**9, 5 * P, 5 * P) is None  # not started: nothing to guard
    a.add_estimate(0, 0.0, 0.0)
    a.add_measurement(0, 0.0)
    assert a.watchdog(4 * P, 5 * P, 5 * P) is None  # the drive holds the last command
    s = a.watchdog(6 * P, 5 * P, 5 * P)  # then 0 A, no brake, for the newest sample seen
    assert (s.status, s.stamp_ns, s.current_a, s.safe_stop) == (
        Status.STALE_MEASUREMENT,
        0,
        0.0,
        False,
    )
    assert a.watchdog(11 * P, 5 * P, 5 * P).safe_stop  # brake only past BRAKE_AFTER_S
    for k in range(1, 4):  # measurements flow (received just now), the observer is silent
        a.add_measurement(k * P, 0.0, received_ns=8 * P)
    s = a.watchdog(3 * P + 6 * P, 5 * P, 5 * P)
    # the brake the watchdog engaged at 11 ms stays: only the law's next command releases it
    assert (s.status, s.stamp_ns, s.safe_stop) == (Status.STALE_ESTIMATE, 3 * P, True)
    assert a.add_estimate(3 * P, 0.0, 0.0) is None  # that sample was answered already


def test_assembly_resync_holds_zero_then_restarts_the_reference_from_the_held_angle():
    a = assembly()
    a.add_estimate(0, 0.0, 0.0)
    a.add_measurement(0, 0.0)
    base = 10**12
    a.add_estimate(base, 0.0, 0.0, initial=True)  # the observer restarted, ahead of y(base)
    assert a.refusal.endswith('kept aside as a restart, used if that measurement comes')
    held = a.add_measurement(base, 0.3)
    assert held.status is Status.RESYNC and held.current_a == 0.0
    samples = []
    for k in range(1, RESYNC_SAMPLES + RECOVERY_SAMPLES + 1):
        a.add_estimate(base + k * P, 0.0, 0.0)
        samples.append(a.add_measurement(base + k * P, 0.3))
    assert {s.status for s in samples[: RESYNC_SAMPLES - 1]} == {Status.RESYNC}
    s = samples[RESYNC_SAMPLES - 1]
    assert s.status is Status.RECOVERING and s.t_s == 0.0 and not s.safe_stop
    assert s.output.error_rad == pytest.approx(0.0)  # the reference starts where the joint is
    assert {x.status for x in samples[RESYNC_SAMPLES:-1]} == {Status.RECOVERING}
    # RECOVERY_SAMPLES later, inside the envelope, the window is over; this frozen joint (y held,
    # the estimates at 0) keeps the law at the current limit, so the state still says RECOVERING
    last = samples[-1]
    assert last.output.bounds_kept and last.stamp_ns >= a.recovering_until_ns
    assert abs(last.current_a) == 20.0 and a.at_limit_run > AT_LIMIT_SAMPLES
    assert last.status is Status.RECOVERING


def test_assembly_resyncs_when_estimates_resume_after_a_long_gap():
    a = assembly()
    a.add_estimate(0, 0.0, 0.0)
    a.add_measurement(0, 0.0)
    for k in range(1, 300):  # the observer is gone; measurements go on
        a.add_measurement(k * P, 0.0)
    a.add_measurement(300 * P, 0.2)
    s = a.add_estimate(300 * P, 0.0, 0.0)  # a new observer, its initial estimate lost
    assert s.status is Status.RESYNC and a.resyncs == 1


def test_assembly_started_away_from_the_reference_start_tracks_from_there():
    a = assembly()
    a.add_estimate(0, 0.0, 0.0)
    s = a.add_measurement(0, 0.4)  # a controller restarted at 0.4 rad
    assert s.status is Status.OK and s.output.error_rad == pytest.approx(0.0)


def test_gate_honours_safe_stop_limit_timeout_and_brake():
    g = CommandGate(timeout_s=0.01, brake_delay_s=0.005)
    assert g.offer(1.0, 0, False, 0) == 'the drive is not active'
    assert g.hold(0) == (0.0, -1, True, 'inactive')
    g.activate()
    assert g.hold(0).brake and g.hold(0).reason == 'no command yet'
    assert g.offer(5.0, 0, False, 0) is None
    assert g.hold(P) == (5.0, 0, False, '')  # first valid command releases the brake
    assert g.offer(5.0, P, True, P) is None
    assert g.hold(2 * P) == (0.0, P, True, 'safe stop')  # safe_stop: 0 A whatever current_a says
    assert 'refused' in g.offer(limits.CURRENT_LIMIT_A + 1.0, 2 * P, False, 2 * P)
    assert g.hold(3 * P).current_a == 0.0 and g.refused == 1
    assert 'refused' in g.offer(float('nan'), 3 * P, False, 3 * P)
    g.offer(2.0, 4 * P, False, 4 * P)
    assert g.hold(4 * P + 10 * P).current_a == 2.0
    late = g.hold(4 * P + 11 * P)  # past the timeout: 0 A, coasting (the brake waits)
    assert late == (0.0, -1, False, 'command timeout') and g.timeouts == 1
    assert g.hold(4 * P + 15 * P).brake is False  # timeout + brake delay: not yet
    braked = g.hold(4 * P + 16 * P)  # beyond it: the brake engages, and stays
    assert braked == (0.0, -1, True, 'command timeout') and g.timeouts == 1
    assert g.hold(4 * P + 12 * P).brake
    g.offer(1.0, 20 * P, False, 20 * P)  # a valid command releases it again
    assert g.hold(20 * P) == (1.0, 20 * P, False, '')
    g.deactivate()
    assert g.hold(0).reason == 'inactive' and g.offer(1.0, 0, False, 0) is not None


def test_gate_takes_a_batch_of_safe_stops_elementwise():
    g = CommandGate()
    g.activate()
    stop = np.array([False, True, False])
    assert g.offer(np.array([1.0, 2.0, 30.0]), 0, stop, 0) is None
    held = g.hold(0)
    assert held.current_a.tolist() == [1.0, 0.0, 0.0]  # stopped and refused elements: 0 A
    assert held.brake.tolist() == [False, True, False]
