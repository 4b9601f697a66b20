# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Controllers, closed loop and stability: behaviour of the control core without ROS."""

import dataclasses
import math

import numpy as np
import pytest

from actuator_controller.laws import (
    CONTROLLER_NAMES,
    CommonConfig,
    NftsmcGains,
    PiGains,
    SmcGains,
    make_controller,
    tanh_sq_over,
)
from actuator_controller.reference import (
    REFERENCE_KINDS,
    PaperTrajectory,
    ReferenceSample,
    fast_trajectory,
    make_reference,
    slow_trajectory,
)
from actuator_core.metrics import compute_run_metrics
from actuator_plant.model import PlantParameters
from actuator_sim.loop import ClosedLoop, Scenario
from actuator_sim.offline import run_scenario
from actuator_sim.scenarios import case1, paper_scenario
from actuator_sim.stability import radius_along_envelope


@pytest.mark.parametrize('name', CONTROLLER_NAMES)
def test_each_controller_holds_zero_error_with_zero_command_on_ideal_plant_at_rest(name):
    scenario = Scenario(
        name='rest',
        controller=name,
        reference='step',
        plant=PlantParameters().ideal(),
        duration_s=0.5,
    )
    loop = ClosedLoop(scenario)
    loop.assembly.reference = type(loop.assembly.reference)(amplitude_rad=0.0)
    trace = loop.run()
    assert np.all(trace['current_a'] == 0.0)
    assert np.all(trace['error_rad'] == 0.0)
    assert np.all(trace['measured_position_rad'] == 0.0)


@pytest.mark.parametrize(
    'reference',
    [
        slow_trajectory(),
        fast_trajectory(),
        make_reference('sine'),
        # the paper's tau = 1 s hides tau's place in the derivatives: another rise time
        PaperTrajectory(frequency_rad_s=math.pi, rise_time_constant_s=0.3),
    ],
)
def test_reference_derivatives_are_analytic(reference):
    t = np.linspace(0.0, 3.0, 30001)
    s = reference.sample(t)
    assert np.allclose(np.gradient(s.position_rad, t)[5:-5], s.velocity_rad_s[5:-5], atol=1e-4)
    assert np.allclose(
        np.gradient(s.velocity_rad_s, t)[5:-5], s.acceleration_rad_s2[5:-5], atol=2e-3
    )


def test_unknown_reference_and_controller_are_refused():
    with pytest.raises(ValueError) as refused:
        make_reference('zigzag')
    kinds = ', '.join(REFERENCE_KINDS)
    assert str(refused.value) == f"reference must be one of {kinds}, got 'zigzag'"
    with pytest.raises(ValueError) as refused:
        make_controller('lqr')
    names = ', '.join(CONTROLLER_NAMES)
    assert str(refused.value) == f"controller must be one of {names}, got 'lqr'"


def test_u_b_is_continuous_through_sigma_zero():
    sigma = np.array([-1e-12, 0.0, 1e-12, 1e-6, 1e-3])
    values = tanh_sq_over(sigma, 0.06)
    assert values[1] == 0.0
    assert np.all(np.isfinite(values))
    assert values[4] == pytest.approx(np.tanh(1e-3 / 0.06) ** 2 / 1e-3)


@pytest.mark.parametrize('tau', [0.1, 0.7, 3.0])
def test_tanh_sq_over_uses_its_series_strictly_below_1e_9_tau(tau):
    """|sigma| < 1e-9 tau: the series sigma/tau^2 (not tanh^2/sigma, nor sigma itself).

    At the threshold itself the tanh formula; for these tau the two differ in the last bit,
    so the side the threshold is on shows.
    """
    below = np.array([-0.5e-9 * tau, 1e-12 * tau, 0.9e-9 * tau])
    assert np.array_equal(tanh_sq_over(below, tau), below / (tau * tau))
    for sigma in below:
        assert tanh_sq_over(float(sigma), tau) == sigma / (tau * tau)
    edge = 1e-9 * tau
    assert tanh_sq_over(edge, tau) == math.tanh(edge / tau) ** 2 / edge
    assert tanh_sq_over(edge, tau) != edge / (tau * tau)


def test_tanh_sq_over_saturates_to_one_over_sigma_for_a_narrow_tau():
    """Far beyond a narrow tau: tanh^2(sigma/tau) = 1, so 1/sigma (the series gives 1e8)."""
    tau = 1e-6
    assert tanh_sq_over(1e-4, tau) == pytest.approx(1e4, rel=1e-12)
    assert tanh_sq_over(np.array([-1e-4, 1e-4]), tau) == pytest.approx([-1e4, 1e4], rel=1e-12)


#: The terms of ControlOutput each law does not compute: NaN (a float), as the state message says.
NOT_COMPUTED = {
    'pi': {
        'rho_rad', 'lower_bound_rad', 'upper_bound_rad', 'z2_rad_s', 'alpha_rad_s',
        'alpha_dot_rad_s2', 'sigma_rad_s', 'u_eq_rad_s2', 'u_sw_rad_s2', 'u_b_rad_s2',
    },
    'smc_eso': {
        'rho_rad', 'lower_bound_rad', 'upper_bound_rad', 'u_b_rad_s2', 'proportional_a',
        'integral_a',
    },
    'pp_nftsmc_eso': {'proportional_a', 'integral_a'},
}  # fmt: skip
NOT_COMPUTED['nftsmc_eso'] = NOT_COMPUTED['smc_eso']


@pytest.mark.parametrize('name', CONTROLLER_NAMES)
def test_each_law_fills_every_term_with_a_float_and_nan_where_it_computes_none(name):
    ctrl = make_controller(name)
    out = ctrl.update(0.01, 0.02, 0.1, 0.5, ReferenceSample(0.01, 0.2, 0.3))
    flags = {'saturated', 'bounds_kept', 'finite'}
    for field, value in out._asdict().items():
        if field in flags:
            assert isinstance(value, bool), (field, value)
        else:
            assert isinstance(value, float), (field, value)
            assert math.isnan(value) == (field in NOT_COMPUTED[name]), (field, value)


@pytest.mark.parametrize('name', CONTROLLER_NAMES)
def test_reset_returns_a_law_to_a_fresh_one(name):
    """After reset() the same inputs give what a new controller gives (the integral at 0)."""
    ref = ReferenceSample(0.01, 0.2, 0.0)  # 1 mrad, 10 mrad/s off: no law with an integral...
    used, fresh = make_controller(name), make_controller(name)
    for k in range(50):
        used.update(k * 1e-3, 0.011, 0.21, 0.0, ref)
    assert (used.integral != 0.0) == used.has_integral  # ...saturates, so each one has moved
    used.reset()
    assert used.integral == 0.0
    assert used.update(0.0, 0.011, 0.21, 0.0, ref) == fresh.update(0.0, 0.011, 0.21, 0.0, ref)


def test_the_smc_law_keeps_no_integral():
    ctrl = make_controller('smc_eso')
    for k in range(20):
        ctrl.update(k * 1e-3, 0.02, 0.1, 0.5, ReferenceSample(0.01, 0.2, 0.3))
    assert ctrl.integral == 0.0 and not ctrl.has_integral


def test_the_smc_law_keeps_no_integral_also_below_the_current_limit():
    """1 urad off and at rest the law commands within the limit (nothing frozen): integral 0."""
    ctrl = make_controller('smc_eso')
    for k in range(20):
        out = ctrl.update(k * 1e-3, 1e-6, 0.0, 0.0, ReferenceSample(0.0, 0.0, 0.0))
        assert not out.saturated and out.finite and out.error_rad == 1e-6
    assert ctrl.integral == 0.0


def test_the_paper_trajectories_carry_their_names():
    assert (slow_trajectory().name, fast_trajectory().name) == ('slow', 'fast')


def test_current_limit_and_anti_windup():
    common = CommonConfig(current_limit_a=1.0)
    pi = make_controller('pi', PiGains(), common)
    ref = ReferenceSample(1.0, 0.0, 0.0)
    for _ in range(2000):  # 2 s of a 1 rad error: far into saturation
        out = pi.update(0.0, 0.0, 0.0, 0.0, ref)
        assert out.current_a == 1.0 and out.saturated
    assert pi.integral == 0.0  # frozen: integrating would push further into the limit
    out = pi.update(0.0, 1.5, 0.0, 0.0, ref)  # reversed and saturated low: still frozen
    assert out.current_a == -1.0 and pi.integral == 0.0
    out = pi.update(0.0, 1.001, 0.0, 0.0, ref)  # back inside the limit: integrates again at once
    assert -1.0 < out.current_a < 0.0 and not out.saturated
    assert pi.integral == pytest.approx(-1e-6)


@pytest.mark.parametrize('error_sign', [1.0, -1.0])
def test_a_current_exactly_at_the_limit_is_not_saturated_and_integrates(error_sign):
    """u_unlimited = +-limit exactly (kp 2 A/rad, e 0.5 rad, limit 1 A): inside, so integrated."""
    pi = make_controller('pi', PiGains(kp_a_rad=2.0), CommonConfig(current_limit_a=1.0))
    out = pi.update(0.0, 0.0, 0.0, 0.0, ReferenceSample(0.5 * error_sign, 0.0, 0.0))
    assert out.current_unlimited_a == out.current_a == error_sign and not out.saturated
    assert pi.integral == 0.5 * error_sign * pi.common.dt_s


def test_an_integral_wound_into_the_low_limit_unwinds_by_any_positive_push():
    """Saturated low, a small positive integrand (0.25) is integrated: it leads out."""
    pi = make_controller('pi', PiGains(kp_a_rad=2.0), CommonConfig(current_limit_a=1.0))
    pi.integral = -10.0  # wound: ki * integral far below -1 A
    out = pi.update(0.0, -0.25, 0.0, 0.0, ReferenceSample(0.0, 0.0, 0.0))
    assert out.current_a == -1.0 and out.saturated
    assert pi.integral == -10.0 + 0.25 * pi.common.dt_s


def test_non_finite_input_gives_zero_current_and_keeps_the_integral():
    ctrl = make_controller('pp_nftsmc_eso')
    out = ctrl.update(0.1, float('nan'), 0.0, 0.0, ReferenceSample(0.0, 0.0, 0.0))
    assert out.current_a == 0.0 and not out.finite
    assert ctrl.integral == 0.0


def test_stability_check_reproduces_the_known_facts():
    worst = {c: max(r for _, r in radius_along_envelope(c)) for c in ('pp_nftsmc_eso', 'smc_eso')}
    assert worst['pp_nftsmc_eso'] < 1.0
    assert worst['smc_eso'] > 10.0  # printed SMC-ESO gains cannot run at 1 kHz
    late_eso = max(r for _, r in radius_along_envelope('pp_nftsmc_eso', eso_delay=1))
    assert late_eso > 1.0  # an ESO one current behind diverges
    slow_loop = max(
        r for _, r in radius_along_envelope('smc_eso', SmcGains(k1_per_s=200.0, k2_per_s=100.0))
    )
    assert slow_loop < 1.0


@pytest.mark.slow
def test_late_eso_current_diverges_in_the_closed_loop_too():
    """The linearised verdict holds in the nonlinear loop.

    Fed u(k-1), the ESO drives the loop into a limit cycle held only by the current limit, with
    several times the normal error.
    """
    loop = ClosedLoop(paper_scenario('late', 'pp_nftsmc_eso', 'fast', 'deep_sea', duration_s=3.0))
    update = loop.eso.update
    previous = {'u': 0.0}

    def late_update(y, u):
        update(y, previous['u'])
        previous['u'] = u

    loop.eso.update = late_update
    trace = loop.run()
    m = compute_run_metrics(
        trace['t_s'], trace['error_rad'], trace['current_a'], saturated=trace['saturated']
    )
    normal = ClosedLoop(
        paper_scenario('ok', 'pp_nftsmc_eso', 'fast', 'deep_sea', duration_s=3.0)
    ).run()
    assert m.diverged or m.saturated_fraction > 0.3
    assert not np.any(normal['saturated'])
    assert np.max(np.abs(trace['error_rad'])) > 3.0 * np.max(np.abs(normal['error_rad'][1000:]))


@pytest.fixture(scope='module')
def case2_metrics():
    return {
        c: run_scenario(paper_scenario(c, c, 'fast', 'deep_sea'))[1]
        for c in ('pi', 'nftsmc_eso', 'pp_nftsmc_eso')
    }


@pytest.mark.slow
def test_case2_ordering_with_margins(case2_metrics):
    pp, nft, pi = (
        case2_metrics[c].max_steady_error_rad for c in ('pp_nftsmc_eso', 'nftsmc_eso', 'pi')
    )
    assert not any(case2_metrics[c].diverged for c in case2_metrics)
    assert pp * 5.0 < nft  # paper: almost 10x
    assert nft * 1.5 < pi


@pytest.mark.slow
def test_case1_pp_stays_inside_its_bounds_and_near_table5():
    for scenario, paper in case1():
        trace, metrics, radius, _ = run_scenario(scenario)
        assert metrics.bounds_kept, scenario.name
        assert not metrics.diverged and radius < 1.0
        assert 0.5 * paper < metrics.max_steady_error_rad < 1.5 * paper, scenario.name


@pytest.mark.slow
def test_batch_run_matches_single_runs():
    scenario = paper_scenario('b', 'pp_nftsmc_eso', 'fast', 'deep_sea', duration_s=1.0)
    single = ClosedLoop(scenario).run()
    batch = ClosedLoop(scenario, batch=3).run()
    assert batch['error_rad'].shape == (1000, 3)
    for i in range(3):
        assert np.allclose(batch['error_rad'][:, i], single['error_rad'], rtol=1e-9, atol=1e-12)


@pytest.mark.slow
def test_four_substeps_are_enough_in_closed_loop():
    coarse = run_scenario(
        paper_scenario('c', 'pp_nftsmc_eso', 'fast', 'deep_sea', duration_s=6.0)
    )[1]
    fine_scenario = paper_scenario('f', 'pp_nftsmc_eso', 'fast', 'deep_sea', duration_s=6.0)
    fine_scenario.plant = dataclasses.replace(fine_scenario.plant, substeps=32)
    fine = run_scenario(fine_scenario)[1]
    assert coarse.max_steady_error_rad == pytest.approx(fine.max_steady_error_rad, rel=0.02)


def test_gains_refuse_out_of_range_values_with_the_name():
    with pytest.raises(ValueError, match='alpha1.*range'):
        NftsmcGains(alpha1=0.0)
    with pytest.raises(ValueError, match='current_limit_a'):
        CommonConfig(current_limit_a=float('inf'))
    with pytest.raises(ValueError, match='k0_per_s'):
        dataclasses.replace(make_controller('pp_nftsmc_eso').gains, k0_per_s=-1.0)


def test_envelope_restarts_when_the_error_leaves_it_and_not_otherwise():
    """An error e beyond h rho restarts (8) at t with rho0 = max(rho0, margin |e|).

    Kept means inside the gains' own envelope, restarted or not. restart_margin 0 keeps the
    paper's clamp.
    """
    from actuator_controller.laws import PpNftsmcGains, make_controller
    from actuator_controller.ppf import PrescribedPerformance
    from actuator_controller.reference import ReferenceSample

    ref = ReferenceSample(0.0, 0.0, 0.0)
    ctrl = make_controller('pp_nftsmc_eso')
    out = ctrl.update(6.0, 0.01, 0.0, 0.0, ref)  # inside (rho(6) ~ 0.06): no restart
    assert bool(out.bounds_kept) and ctrl.envelope_restarts == 0
    out = ctrl.update(6.001, 0.3, 0.0, 0.0, ref)  # beyond: restarted at t = 6.001 with rho0 = 0.6
    assert ctrl.envelope_restarts == 1 and ctrl.envelope_start_s == 6.001
    assert out.rho_rad == pytest.approx(0.6) and not bool(
        out.bounds_kept
    )  # the violation is still reported
    # inside the restarted envelope: no second restart, but not kept (outside the gains' own,
    # rho(6.002) ~ 0.06), so the status says RECOVERING; kept again once back inside it
    assert not bool(ctrl.update(6.002, 0.3, 0.0, 0.0, ref).bounds_kept)
    assert ctrl.envelope_restarts == 1
    assert bool(ctrl.update(6.003, 0.01, 0.0, 0.0, ref).bounds_kept)
    assert ctrl.envelope_restarts == 1
    ctrl.reset()
    assert ctrl.envelope_start_s == 0.0 and ctrl.envelope_rho0_rad == 0.25
    assert ctrl.envelope_restarts == 0  # a new run counts its own restarts
    paper = make_controller(
        'pp_nftsmc_eso', PpNftsmcGains(ppf=PrescribedPerformance(restart_margin=0.0))
    )
    out = paper.update(6.001, 0.3, 0.0, 0.0, ref)
    assert not bool(out.bounds_kept) and paper.envelope_restarts == 0 and out.rho_rad < 0.1


def test_every_envelope_restart_is_counted_and_a_batch_restarts_only_its_runs_outside():
    """Two exits: two restarts. Arrays: the run inside keeps its envelope, the other restarts."""
    ref = ReferenceSample(0.0, 0.0, 0.0)
    ctrl = make_controller('pp_nftsmc_eso')
    ctrl.update(6.001, 0.3, 0.0, 0.0, ref)  # beyond rho(6.001): restart with rho0 = 0.6
    out = ctrl.update(6.002, 5.0, 0.0, 0.0, ref)  # beyond 0.6: a second restart, rho0 = 10
    assert ctrl.envelope_restarts == 2 and out.rho_rad == pytest.approx(10.0)
    batch = make_controller('pp_nftsmc_eso')
    y = np.array([0.01, 0.3])  # inside rho(6) ~ 0.06, and beyond it
    out = batch.update(6.0, y, np.zeros(2), np.zeros(2), ref)
    assert list(batch.envelope_start_s) == [0.0, 6.0]
    assert list(batch.envelope_rho0_rad) == pytest.approx([0.25, 0.6])
    assert out.rho_rad[0] == pytest.approx(batch.gains.ppf.rho_derivatives(6.0, 0.25)[0])
    assert list(out.bounds_kept) == [True, False] and batch.envelope_restarts == 1
    out = batch.update(6.001, np.array([0.4, 0.01]), np.zeros(2), np.zeros(2), ref)
    assert list(out.bounds_kept) == [False, True]  # now the first leaves; the second is inside
    assert list(batch.envelope_start_s) == [6.001, 6.0]  # the second keeps its restart ...
    assert list(batch.envelope_rho0_rad) == pytest.approx([0.8, 0.6])  # ... and its rho0


def test_any_positive_restart_margin_restarts_the_envelope():
    """restart_margin 0.5 restarts too; rho0 is then max(rho0, 0.5 |e|) = the gains' 0.25."""
    from actuator_controller.laws import PpNftsmcGains
    from actuator_controller.ppf import PrescribedPerformance

    ctrl = make_controller(
        'pp_nftsmc_eso', PpNftsmcGains(ppf=PrescribedPerformance(restart_margin=0.5))
    )
    out = ctrl.update(6.0, 0.3, 0.0, 0.0, ReferenceSample(0.0, 0.0, 0.0))
    assert ctrl.envelope_restarts == 1 and ctrl.envelope_start_s == 6.0
    assert out.rho_rad == pytest.approx(0.25)  # restarted at t: rho(0) = rho0


@pytest.mark.slow
@pytest.mark.parametrize('restart_margin, recovers', [(2.0, True), (0.0, False)])
def test_loop_recovers_from_a_40_ms_current_dropout_only_with_envelope_restarts(
    restart_margin, recovers
):
    """40 ms of 0 A at t = 5 s throws the error out of the envelope.

    As a drive watchdog would after a controller stall.
    """
    from actuator_controller.laws import PpNftsmcGains
    from actuator_controller.ppf import PrescribedPerformance

    scenario = paper_scenario(
        'dropout',
        'pp_nftsmc_eso',
        'fast',
        'deep_sea',
        8.0,
        gains=PpNftsmcGains(ppf=PrescribedPerformance(restart_margin=restart_margin)),
    )
    loop = ClosedLoop(scenario)
    errors = []
    for k in range(scenario.samples):
        if k == 5000:
            loop.last_current = 0.0  # the plant holds 0 A over the next 40 samples
        errors.append(abs(float(loop.step(command_lost=5000 <= k < 5040)['error_rad'])))
    worst_late = max(errors[7000:])
    assert max(errors[5000:5200]) > 0.05  # the dropout did throw it out
    assert (worst_late < 2e-3) == recovers, worst_late
