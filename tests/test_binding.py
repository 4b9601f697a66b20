# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Issue 21 at core level, message by message: stamps bound to samples seen, plausibility, clocks.

Each case of the issue's attack on the loop's trust model is replayed through the nodes' own
core objects (no processes, deterministic).
"""

import math

import pytest

from actuator_controller.laws import make_controller
from actuator_controller.reference import make_reference
from actuator_core import limits
from actuator_core.assembly import ControlSampleAssembly
from actuator_core.binding import (
    PLAUSIBILITY_MEMORY_S,
    SAFE_STOP_SAMPLES,
    CommandBinding,
    MeasurementPlausibility,
    SeenSamples,
    late_window_samples,
)
from actuator_core.clock import Schedule, SteppedClock
from actuator_core.gate import CommandGate
from actuator_core.pairing import ObserverInputPairing
from actuator_core.status import CONTROLLED, Status
from actuator_core.timebase import StampCheck, Verdict
from actuator_eso.observer import EsoGains, ExtendedStateObserver

pytestmark = pytest.mark.unit

P = 1_000_000  # 1 ms in ns
T0 = 1_700_000_000 * 10**9  # a wall-clock stamp


def assembly():
    law = make_controller('pp_nftsmc_eso')
    return ControlSampleAssembly(law, make_reference('fast'), P)


def pairing(**kwargs):
    eso = ExtendedStateObserver(EsoGains(), 1e-3)
    return ObserverInputPairing(eso, P, eso.correction, 1, **kwargs), eso


# --- the controller binds estimates to measurements it received ------------------------------
def _run(a, k_end, rogue=None):
    """Feed y(k), x_hat(k) for k < k_end; ``rogue(a, k)`` may inject before each measurement."""
    out = []
    for k in range(k_end):
        a.add_estimate(T0 + k * P, 0.0, 0.0, T0 + (k - 1) * P, 0.0, 0.0, initial=k == 0)
        if rogue is not None:
            rogue(a, k)
        out.append(a.add_measurement(T0 + k * P, 1e-4 * k))
    return out


def test_estimates_stamped_ahead_are_refused_with_the_reason_and_change_no_command():
    clean = _run(assembly(), 60)

    def burst(a, k):  # 20 estimates 1-50 ms ahead, chosen for +20 A
        if k % 10 == 5:
            for ahead in range(2, 52, 2):
                stamp = T0 + (k + ahead) * P
                assert a.add_estimate(stamp, -5.0, -2000.0) is None
                assert a.refusal == (  # the newest measurement seen is y(k-1)
                    f'estimate stamped {stamp} ns refused: {ahead + 1} ms ahead of the newest '
                    'measurement seen (at most 1 sample)'
                )

    a = assembly()
    attacked = _run(a, 60, burst)
    assert a.refused == 6 * 25
    assert [s.current_a for s in attacked] == [s.current_a for s in clean]
    # the statuses too: the attack changed nothing (the start's samples at the limit say
    # RECOVERING in both, AT_LIMIT_SAMPLES)
    assert [s.status for s in attacked] == [s.status for s in clean]
    assert {s.status for s in attacked[1:]} <= {Status.OK, Status.RECOVERING}


def test_two_different_estimates_for_one_sample_give_zero_not_the_racers_current():
    a = assembly()
    _run(a, 10)
    k = 10
    assert a.add_estimate(T0 + k * P, 5.0, 2000.0, T0 + (k - 1) * P) is None  # first: a rogue
    assert a.add_estimate(T0 + k * P, 0.0, 0.0, T0 + (k - 1) * P) is None  # then the ESO
    assert a.refusal == (
        f'two different estimates for sample {T0 + k * P} ns (a second publisher?): neither '
        'used, 0 A for that sample'
    )
    s = a.add_measurement(T0 + k * P, 1e-3)
    assert (s.status, s.current_a, s.safe_stop) == (Status.INVALID_INPUT, 0.0, False)
    assert a.conflicts == 1


def test_corrected_velocity_beyond_the_limit_is_refused():
    a = assembly()
    _run(a, 3)
    commanded = a.commanded[1]
    # x2 in range, but the correction for the current commanded pushes it beyond the limit
    a.add_estimate(T0 + 3 * P, 19.9, 0.0, T0 + 2 * P, commanded - 20.0, 0.06)
    s = a.add_measurement(T0 + 3 * P, 3e-4)
    assert s.status is Status.INVALID_INPUT and s.current_a == 0.0
    assert 'x2_hat corrected for the current commanded is' in a.refusal
    assert a.refusal.endswith(f'rad/s, beyond +-{limits.VELOCITY_LIMIT_RAD_S:g}')


# --- the ESO binds commands to measurements it received ---------------------------------------
def test_pairing_refuses_commands_ahead_and_keeps_the_genuine_ones():
    clean, clean_eso = pairing()
    attacked, eso = pairing()
    for k in range(40):
        stamp = T0 + k * P
        for p in (clean, attacked):
            p.add_measurement(stamp, 1e-4 * k)
        if k % 7 == 3:
            for ahead in (2, 5, 30):
                assert attacked.add_command(stamp + ahead * P, 20.0) == []
                assert attacked.refusal == (
                    f'command stamped {stamp + ahead * P} ns refused: {ahead:g} ms ahead of the '
                    'newest measurement received'
                )
            assert attacked.add_command(stamp + P // 2, 20.0) == []
            assert attacked.refusal.endswith('off the sample grid')
        for p in (clean, attacked):
            p.add_command(stamp, 0.5)
    assert eso.state == clean_eso.state and attacked.refused == 6 * 4
    assert attacked.substituted == 0


def test_pairing_drops_a_sample_two_different_commands_claim():
    p, _ = pairing()
    p.add_measurement(T0, 0.0)
    p.add_command(T0, 1.0)
    p.add_measurement(T0 + P, 0.0)
    assert p.add_command(T0 + 2 * P, 20.0) == []  # the next sample: parked, y(2) not in yet
    assert p.add_command(T0 + 2 * P, -3.0) == []  # ... and the genuine one
    assert p.refusal.startswith(f'two different commands for sample {T0 + 2 * P} ns')
    p.add_command(T0 + P, 1.0)
    p.add_measurement(T0 + 2 * P, 0.0)
    (e,) = p.add_measurement(T0 + 3 * P, 0.0)  # sample 2 substituted, not the rogue's 20 A
    assert e.substituted and e.input_current_a == 1.0 and p.conflicts == 1


def test_pairing_restarts_after_a_gap_instead_of_back_filling_it():
    p, eso = pairing(restart_gap_samples=10)
    for k in range(5):
        p.add_measurement(T0 + k * P, 0.0)
        p.add_command(T0 + k * P, 1.0)
    out = p.add_measurement(T0 + 20 * P, 0.3)  # 15 samples missed: a stall
    assert out[0].initial and out[0].sample_ns == T0 + 20 * P and p.gap_restarts == 1
    assert eso.state == (0.3, 0.0, 0.0)


# --- the joint binds commands to samples it produced (the integrator wires this) -------------
def test_command_binding_windows():
    b = CommandBinding(P)
    late = b.late_samples
    assert late == late_window_samples(P) == 9  # 10 ms command timeout, one sample kept
    assert b.check(T0, False) == 'command no sample seen yet: refused'
    for k in range(20):
        b.produced(T0 + k * P)
    k = T0 + 19 * P
    assert b.check(k - late * P, False) == ''  # the oldest sample of the late window
    assert b.check(k - P, False) == ''  # k-1: late but in the window, and newer
    assert b.check(k - 2 * P, False) == (
        f'command for sample {k - 2 * P} ns is not newer than the one applied ({k - P} ns; a '
        'duplicate or a replay): refused'
    )
    assert b.check(k, False) == ''  # k
    assert b.check(k, False) == (
        f'command for sample {k} ns is not newer than the one applied ({k} ns; a duplicate or '
        'a replay): refused'
    )
    b.produced(k + P)
    assert b.check(k - late * P, False) == (
        f'command for sample {k - late * P} ns is {late + 1} ms old (the window is the newest '
        f'sample and {late} before): refused'
    )
    assert b.check(k + 2 * P, False) == (
        f'command stamped 1.000 ms ahead of the newest sample seen ({k + P} ns): refused'
    )
    for stamp in (0, -5, T0 - 3600 * 10**9, k + P // 3):  # zero, negative, an old bag, off grid
        assert b.check(stamp, False).endswith('refused')
    assert b.check(k + 2 * P, True).startswith('safe stop stamped 1.000 ms ahead')
    assert b.check(T0, True) == '' and b.check(T0, True) == ''  # a stop: any recent sample, again
    assert b.applied_ns == k and b.refused == 10


def test_a_late_current_is_valid_for_the_timeout_from_the_sample_it_answers():
    """Accepted 5 samples late: the gate's 0 A comes 5 ms sooner; a safe stop holds from now."""
    timeout_ns = int(round(limits.COMMAND_TIMEOUT_S * 1e9))
    for late in (0, 5):
        b, gate = CommandBinding(P), CommandGate()
        gate.activate()
        for k in range(20):
            b.produced(T0 + k * P)
        now = T0 + 19 * P + P // 2
        stamp = T0 + (19 - late) * P
        assert b.check(stamp, False) == ''
        gate.offer(1.5, stamp, False, b.valid_from_ns(stamp, False, now))
        assert gate.hold(now + timeout_ns - late * P).current_a == 1.5
        assert gate.hold(now + timeout_ns - late * P + 1).reason == 'command timeout'
        assert b.valid_from_ns(stamp, True, now) == now


def test_the_late_window_is_what_the_command_timeout_still_covers():
    """9 samples at 1 kHz, 4 at 500 Hz, and at least one whatever the period."""
    assert late_window_samples(P, 0.01) == 9
    assert late_window_samples(2 * P, 0.01) == 4
    assert late_window_samples(P, 0.002) == 1
    assert late_window_samples(20 * P, 0.01) == 1
    assert late_window_samples(P) == int(round(limits.COMMAND_TIMEOUT_S * 1e3)) - 1


def test_command_binding_keeps_safe_stops_for_its_window_only():
    b = CommandBinding(P)
    for k in range(SAFE_STOP_SAMPLES + 5):
        b.produced(k * P + T0)
    assert b.check(T0, True).endswith('answers no sample this joint produced: refused')
    assert b.check(T0 + 5 * P, True) == ''
    b.reset()
    assert b.check(T0 + 5 * P, True) == 'safe stop no sample seen yet: refused'


def test_seen_samples_bound():
    s = SeenSamples(P, depth=3)
    for k in range(5):
        s.add(k * P)
    assert 4 * P in s and P not in s and s.newest_ns == 4 * P
    assert s.ahead(5 * P, 1) == '' and s.ahead(6 * P, 1).startswith('stamped 2.000 ms ahead')


# --- stamps: refused ones move nothing; what a stamp can hold -----------------------------
def test_stamp_check_limit_and_invalid_stamps_never_move_the_newest():
    c = StampCheck(P, sim=True, future_tolerance_ns=0)
    assert c.check(10 * P, 0) is Verdict.OK
    assert c.check(11 * P, 0, limit_ns=10 * P) is Verdict.FUTURE  # beyond what was seen
    sec_max = (2**31 - 1) * 10**9
    assert c.check(sec_max, 0) is Verdict.INVALID and c.check(-P, 0) is Verdict.INVALID
    assert c.last_ns == 10 * P and c.check(11 * P, 0) is Verdict.OK
    rt = StampCheck(P, sim=False, future_tolerance_ns=int(limits.FUTURE_STAMP_TOLERANCE_S * 1e9))
    assert rt.check(T0, T0) is Verdict.OK
    assert rt.check(T0 + 3 * P, T0) is Verdict.FUTURE  # 3 ms ahead on one host: refused
    assert rt.check(T0 + P, T0 + P) is Verdict.OK and rt.last_ns == T0 + P


# --- plausibility ----------------------------------------------------------------------------
def _offer(m, stamp, y):
    """One measurement through check/accept/refuse as a node does; return the reason."""
    why = m.check(stamp, y)
    if why:
        m.refuse(stamp, y)
    else:
        m.accept(stamp, y)
    return why


def test_a_20_mrad_glitch_is_refused_the_next_genuine_sample_is_not():
    m = MeasurementPlausibility()
    v = 8.8  # rad/s, the fast trajectory's peak
    for k in range(10):
        assert _offer(m, k * P, v * k * 1e-3) == ''
    y = v * 10e-3 - 0.02  # implies -11.2 rad/s: within the velocity limit, not its change
    assert _offer(m, 10 * P, y) == (
        f'measurement {y:.6g} rad changes the implied velocity by -20 rad/s in 1 ms '
        f'(limit {limits.ACCELERATION_LIMIT_RAD_S2:g} rad/s^2): refused'
    )
    y = v * 11e-3 + 0.04  # the other sign: 28.8 rad/s since the last sample accepted
    assert _offer(m, 11 * P, y) == (
        f'measurement {y:.6g} rad implies {(y - v * 9e-3) / 2e-3:.4g} rad/s since the last one '
        'accepted (limit 20 rad/s): refused'
    )
    assert _offer(m, 12 * P, v * 12e-3) == ''
    assert _offer(m, 13 * P, 5.0).startswith('measurement 5 rad implies')
    assert m.refused == 3


def test_a_step_that_persists_becomes_the_baseline():
    m = MeasurementPlausibility()
    for k in range(5):
        _offer(m, k * P, 0.0)
    assert [m.refuse(k * P, 1.0) for k in range(5, 8) if m.check(k * P, 1.0)] == [
        False,
        False,
        True,
    ]
    assert m.check(8 * P, 1.0) == '' and m.rebases == 1


@pytest.mark.slow
def test_the_paper_runs_pass_the_plausibility_check():
    from actuator_sim.scenarios import case2

    scenario = dict((s.name, s) for s, _ in case2(1.5))['case2_pp_nftsmc_eso']
    from actuator_sim.loop import ClosedLoop

    y = ClosedLoop(scenario).run()['measured_position_rad']
    m = MeasurementPlausibility()
    assert [k for k, v in enumerate(y) if _offer(m, k * P, float(v))] == []
    assert max(abs(y[1:] - y[:-1])) > 5e-3  # the fast trajectory moved at its peak speed


# --- clocks: ages are monotonic ---------------------------------------------------------------
@pytest.mark.parametrize('step_s', [-10.0, 10.0])
def test_a_wall_clock_step_neither_silences_nor_races_the_watchdog(step_s):
    clock = SteppedClock()
    a = assembly()
    start = clock.wall_ns()
    for k in range(20):
        stamp = start + k * P
        a.add_estimate(stamp, 0.0, 0.0, stamp - P, 0.0, 0.0, k == 0, clock.now_ns())
        a.add_measurement(stamp, 0.0, clock.now_ns())
        clock.advance(P)
    clock.step_wall(int(step_s * 1e9))
    assert a.watchdog(clock.now_ns(), 5 * P, 5 * P) is None  # fresh: no stop from the step
    clock.advance(5 * P)
    s = a.watchdog(clock.now_ns(), 5 * P, 5 * P)
    assert s.status is Status.STALE_MEASUREMENT and s.stamp_ns == start + 19 * P
    assert (s.current_a, s.safe_stop) == (0.0, False)


def test_schedule_skips_missed_deadlines_instead_of_racing():
    s = Schedule(P, 0)
    assert s.next(0) == (P, 0)
    deadline, skipped = s.next(7 * P + 10)  # a 7 ms stall
    assert (deadline, skipped) == (8 * P, 6) and s.next(8 * P) == (9 * P, 0)
    clock = SteppedClock()
    clock.sleep_until(clock.now_ns() + 3 * P)
    assert clock.now_ns() == 10**9 + 3 * P


# --- statuses ---------------------------------------------------------------------------------
def test_recovering_is_controlled_and_not_a_safe_stop():
    assert Status.RECOVERING.controlled and not Status.RECOVERING.safe_stop
    assert Status.OK in CONTROLLED and Status.RESYNC.safe_stop
    assert math.isclose(limits.DISTURBANCE_LIMIT_RAD_S2 / limits.CURRENT_ACCELERATION_RAD_S2, 4)
    assert limits.input_current_gain_limit(1e-3) == pytest.approx(2 * 1e-3 * limits.THETA1N)


def test_a_state_never_says_ok_while_the_error_is_outside_the_envelope():
    a = assembly()
    _run(a, 200)
    a.add_estimate(T0 + 200 * P, 0.0, 0.0, T0 + 199 * P)
    y_d = make_reference('fast').sample(0.2).position_rad
    s = a.add_measurement(T0 + 200 * P, y_d + 0.3)  # rho(0.2 s) < 0.25 rad: outside
    assert not s.output.bounds_kept and s.status is Status.RECOVERING and not s.safe_stop
    assert s.current_a == s.output.current_a  # the law still commands


# --- boundaries of the windows and the plausibility limits (mutation survivors) ---------------
S = 1_000_000_000  # 1 s in ns


def test_how_far_ahead_and_how_old_are_said_in_milliseconds():
    """The reasons give the exact distance: 1000.000 ms ahead, 999 ms old."""
    seen = SeenSamples(P)
    seen.add(T0)
    assert seen.ahead(T0 + S) == (f'stamped 1000.000 ms ahead of the newest sample seen ({T0} ns)')
    b = CommandBinding(P, late_samples=999, safe_stop_samples=1000)
    for k in range(1000):
        b.produced(T0 + k * P)
    b.late_samples = 998  # the oldest sample kept is now one beyond the window
    assert b.check(T0, False) == (
        f'command for sample {T0} ns is 999 ms old (the window is the newest sample and 998 '
        'before): refused'
    )


def test_the_binding_keeps_the_late_window_and_no_more_when_safe_stops_have_a_shorter_one():
    """History = max(safe-stop window, late window + 1): k-3 answerable with 3 late samples."""
    b = CommandBinding(P, late_samples=3, safe_stop_samples=1)
    for k in range(10):
        b.produced(T0 + k * P)
    assert b.check(T0 + 6 * P, False) == ''  # k - 3 of the newest (k = 9)
    assert 'answers no sample this joint produced' in b.check(T0 + 5 * P, True)  # k - 4: gone


def test_a_reset_binding_takes_the_first_command_of_its_new_run():
    """After reset() nothing was applied: any sample produced since may be answered."""
    b = CommandBinding(P)
    b.produced(T0)
    assert b.check(T0, False) == ''
    b.reset()
    b.produced(T0 - 5 * P)  # a new run may start earlier (sim restarts its clock)
    assert b.check(T0 - 5 * P, False) == ''
    assert b.applied_ns == T0 - 5 * P


def _plausibility(**kw):
    """Small binary-exact limits, so that every boundary is hit exactly."""
    return MeasurementPlausibility(**{'confirm_samples': 2, **kw})


def test_the_velocity_limit_allows_twice_the_noise_over_the_interval_and_is_inclusive():
    """|v| <= limit + 2 noise / dt passes; 1 rad/s + 2 * 0.25 rad / 0.5 s = 2 rad/s here."""
    half = S // 2
    for y, ok in [(1.0, True), (0.9, True), (1.1, False), (-1.0, True), (-1.1, False)]:
        m = _plausibility(velocity_limit_rad_s=1.0, noise_rad=0.25)
        m.accept(T0, 0.0)
        assert (m.check(T0 + half, y) == '') is ok, y


def test_the_acceleration_limit_is_half_the_two_intervals_plus_four_noises_and_inclusive():
    """|dv| <= a (dt0 + dt) / 2 + 4 noise / dt: 8 * 0.0625 + 4 / 64 / 0.0625 = 1.5 rad/s."""
    dt = S // 16  # 0.0625 s, within the 0.1 s memory
    for v, ok in [(1.5, True), (1.6, False), (-1.5, True), (-1.6, False)]:
        m = _plausibility(
            velocity_limit_rad_s=1e3, acceleration_limit_rad_s2=8.0, noise_rad=1.0 / 64
        )
        m.accept(T0, 0.0)
        m.accept(T0 + dt, 0.0)  # v0 = 0 over dt0 = 0.0625 s
        assert (m.check(T0 + 2 * dt, v * 0.0625) == '') is ok, v


def test_the_velocity_is_remembered_for_the_memory_interval_inclusive_and_no_longer():
    """An interval of exactly 0.1 s still judges the change of velocity; a longer one not."""
    memory_ns = int(PLAUSIBILITY_MEMORY_S * 1e9)
    assert memory_ns * 1e-9 == PLAUSIBILITY_MEMORY_S
    for gap_ns, judged in [(memory_ns, True), (memory_ns + P, False)]:
        m = _plausibility(velocity_limit_rad_s=100.0, acceleration_limit_rad_s2=1.0)
        m.accept(T0, 0.0)
        m.accept(T0 + gap_ns, 1.0)  # 10 rad/s over this interval (about)
        why = m.check(T0 + gap_ns + P, 1.0)  # at rest again
        assert bool(why) is judged, gap_ns
        if judged:
            assert 'changes the implied velocity by' in why
        m2 = _plausibility(velocity_limit_rad_s=100.0, acceleration_limit_rad_s2=1.0)
        m2.accept(T0, 0.0)
        m2.accept(T0 + P, 0.0)
        assert bool(m2.check(T0 + P + gap_ns, 1.0)) is judged, gap_ns  # the new interval


def test_a_repeated_stamp_is_left_to_the_stamp_check_and_moves_nothing():
    """Checking and accepting the newest stamp again: no division by zero, no new velocity."""
    m = _plausibility()
    m.accept(T0, 0.5)
    assert m.check(T0, 50.0) == ''
    m.accept(T0, 0.5)
    assert m.velocity is None and m.last == (T0, 0.5)


def test_candidates_of_a_step_must_agree_and_follow_in_time():
    """A candidate implausible from the previous one, or not after it, starts a new chain."""
    m = _plausibility(velocity_limit_rad_s=1.0)
    m.accept(T0, 0.0)
    assert m.refuse(T0 + P, 5.0) is False
    assert m.refuse(T0 + 2 * P, -5.0) is False  # disagrees with 5.0: a new chain of one
    assert m.refuse(T0 + 3 * P, -5.0) is True  # two that agree: a real step
    m.reset()
    m.accept(T0, 0.0)
    assert m.refuse(T0 + 2 * P, 5.0) is False
    assert m.refuse(T0 + 2 * P, 5.0) is False  # the same stamp again
    assert m.refuse(T0 + P, 5.0) is False  # an earlier stamp
    assert m.candidates == [(T0 + P, 5.0)]


def test_rebases_are_counted():
    m = _plausibility()
    m.rebase(T0, 0.0)
    m.rebase(T0 + P, 1.0)
    assert m.rebases == 2 and m.last == (T0 + P, 1.0)


# --- a step of the wall clock in a running loop ------------------------------------------------
@pytest.mark.parametrize('step_s', [-5e-3, 5e-3, -1.0, 1.0])
def test_a_wall_clock_step_in_every_object_of_a_running_loop_refuses_no_stamp(step_s):
    """One host's wall clock steps under the joint, the observer and the controller at once.

    The joint's stamps count monotonic periods from a wall-clock anchor; each receiver judges
    them against its own stamp time (StampClock), anchored when it started: after the step no
    stamp is ahead and none is a jump, in either direction, by a sample period or by a second.
    (Judged against the wall clock, a step back of 5 ms made every later stamp 'ahead'.)
    """
    from actuator_core.clock import StampClock
    from actuator_core.timebase import StampCheck, Verdict

    host = SteppedClock()
    joint = StampClock(host)
    receivers = {name: (StampClock(host), StampCheck(P, False, 2 * P)) for name in ('eso', 'ctl')}
    start = joint.at(host.now_ns())
    verdicts = []
    for k in range(2000):
        if k == 1000:
            host.step_wall(int(step_s * 1e9))
        stamp = start + k * P  # the joint's sample k
        host.advance(P // 5)  # the transport
        for stamp_clock, check in receivers.values():
            verdicts.append(check.check(stamp, stamp_clock.now_ns()))
        host.advance(P - P // 5)
    assert set(verdicts) == {Verdict.OK}
    assert all(check.refused_future == check.jumps == 0 for _, check in receivers.values())
    # the wall clock the receivers no longer judge by did step
    assert StampClock(host).now_ns() - receivers['eso'][0].now_ns() == int(step_s * 1e9)


def test_a_time_base_ahead_of_the_receivers_is_adopted_after_a_stream_not_a_stray_stamp():
    """A joint restarted after a step forward: its stamps are ahead of the receiver's stamp time.

    A stray stamp ahead is refused; FUTURE_STREAM_SAMPLES of them in a row, one period apart, are
    a new time base: a JUMP, which the receiver adopts (its restart policy resyncs), and the
    stream goes on OK.
    """
    from actuator_core.clock import StampClock
    from actuator_core.timebase import FUTURE_STREAM_SAMPLES, StampCheck, Verdict

    host = SteppedClock()
    stamp_clock, check = StampClock(host), StampCheck(P, False, 2 * P)
    base = stamp_clock.now_ns()
    assert check.check(base, stamp_clock.now_ns()) is Verdict.OK
    assert check.check(base + 10**9, stamp_clock.now_ns()) is Verdict.FUTURE  # a stray one
    host.advance(P)
    ahead = base + 10**9  # the restarted joint's base: one second ahead
    verdicts = []
    for k in range(FUTURE_STREAM_SAMPLES + 3):
        stamp = ahead + k * P
        verdict = check.check(stamp, stamp_clock.now_ns())
        if verdict is Verdict.JUMP:
            stamp_clock.adopt(stamp, host.now_ns())
        verdicts.append(verdict)
        host.advance(P)
    assert (
        verdicts
        == [Verdict.FUTURE] * (FUTURE_STREAM_SAMPLES - 1) + [Verdict.JUMP] + [Verdict.OK] * 3
    )
    # a stream broken by a genuine stamp starts counting again
    fresh = StampCheck(P, False, 2 * P)
    now = stamp_clock.now_ns()
    assert fresh.check(now, now) is Verdict.OK
    for k in range(FUTURE_STREAM_SAMPLES - 1):
        assert fresh.check(now + 10**9 + k * P, now) is Verdict.FUTURE
    assert fresh.check(now + P, now) is Verdict.OK  # the genuine next sample
    assert fresh.check(now + 10**9 + FUTURE_STREAM_SAMPLES * P, now) is Verdict.FUTURE


def test_a_stream_ahead_counts_anew_after_a_genuine_stamp_a_jump_and_a_reset():
    """FUTURE_STREAM_SAMPLES in a row on one grid, counted from 1 after each interruption.

    A genuine stamp, a JUMP (the receiver not adopting it: the stream stays ahead) and a reset
    each end the run; the stream's grid goes on across them. After a JUMP the stream's newest is
    its stamp: a duplicate of it, once the receiver's time got there, is OLD.
    """
    from actuator_core.timebase import FUTURE_STREAM_SAMPLES as N
    from actuator_core.timebase import StampCheck, Verdict

    def stream(first_ns, count, now_ns):
        return [check.check(first_ns + k * P, now_ns) for k in range(count)]

    check, now = StampCheck(P, False, 2 * P), 5 * 10**9
    first = now + 10**9
    runs = [Verdict.FUTURE] * (N - 1) + [Verdict.JUMP]
    assert check.check(now, now) is Verdict.OK
    assert stream(first, 30, now) == [Verdict.FUTURE] * 30
    assert check.check(now + P, now) is Verdict.OK  # genuine: the run ends
    assert stream(first + 30 * P, N, now) == runs
    assert (check.jumps, check.refused_future) == (1, 30 + N - 1)
    assert stream(first + (30 + N) * P, N, now) == runs  # still ahead after the JUMP
    assert check.jumps == 2
    newest = first + (30 + 2 * N - 1) * P
    assert check.check(newest, newest) is Verdict.OLD
    check.reset()
    assert stream(newest + P, N, now) == runs


def test_injected_wall_clock_steps_move_the_wall_clock_of_every_clock_in_the_process(monkeypatch):
    """ACTUATOR_WALL_CLOCK_STEPS: at monotonic time T the wall clock steps, never the monotonic."""
    import time as real_time

    from actuator_core.clock import STEPS_ENV, Clock

    now_s = real_time.monotonic()
    monkeypatch.setenv(STEPS_ENV, f'{now_s - 1.0}:-0.5,{now_s + 3600.0}:2.0')
    clock = Clock()
    drift = clock.wall_ns() - real_time.time_ns()
    assert -0.5e9 - 1e7 < drift < -0.5e9 + 1e7  # the past step applies, the future one not yet
    assert abs(clock.now_ns() - real_time.monotonic_ns()) < 1e7
    monkeypatch.delenv(STEPS_ENV)
    assert abs(Clock().wall_ns() - real_time.time_ns()) < 1e7
