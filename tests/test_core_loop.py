# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The offline closed loop (actuator_sim.loop.ClosedLoop): its joint, its law, what run() gives."""

import dataclasses
import math

import numpy as np
import pytest

from actuator_controller.laws import CommonConfig, ControlOutput
from actuator_controller.reference import StepReference
from actuator_core.limits import DIVERGENCE_ERROR_RAD
from actuator_core.status import Status
from actuator_plant.encoder import EncoderParameters
from actuator_plant.model import PlantParameters
from actuator_sim.loop import TRACE_FIELDS, ClosedLoop, Scenario


def _ideal(**kwargs) -> Scenario:
    """Return a 50 ms run of the fast trajectory on the loss-free joint (model (5), d = 0)."""
    return Scenario(name='ideal', plant=PlantParameters().ideal(), duration_s=0.05, **kwargs)


def test_the_loop_joint_has_the_scenario_encoder_delay_and_torque_loop():
    """Encoder: y on its grid. Delay 2: the first command moves the joint 2 samples later.

    Torque loop tau: the first interval gets the mean of i(t) = i*(1 - exp(-t/tau)), so the
    loss-free joint, linear and at rest, gains that share of the velocity it gains without.
    """
    plain = ClosedLoop(_ideal()).run()
    v = plain['true_velocity_rad_s']
    assert v[1] != 0.0
    delayed = ClosedLoop(_ideal(command_delay_samples=2)).run()['true_velocity_rad_s']
    assert (delayed[1], delayed[2], delayed[3]) == (0.0, 0.0, v[1])
    tau, dt = 2e-3, 1e-3
    lagged = ClosedLoop(_ideal(torque_time_constant_s=tau)).run()['true_velocity_rad_s']
    share = 1.0 - (tau / dt) * (1.0 - math.exp(-dt / tau))
    assert lagged[1] == pytest.approx(share * v[1], rel=1e-9)
    encoder = EncoderParameters(counts_per_rev=4096)
    y = ClosedLoop(_ideal(encoder=encoder)).run()['measured_position_rad']
    counts = y / (2.0 * math.pi / 4096)
    assert np.array_equal(counts, np.round(counts)) and np.any(counts != 0.0)
    assert not np.array_equal(y, plain['measured_position_rad'])


def test_the_loop_law_has_the_scenario_common_config():
    """A 2 A current limit: the law's commands stay within it and saturate (the paper's: 20 A)."""
    trace = ClosedLoop(_ideal(common=CommonConfig(current_limit_a=2.0))).run()
    assert np.max(np.abs(trace['current_a'])) == 2.0 and np.any(trace['saturated'] == 1.0)


def test_pi_in_the_loop_runs_on_the_measurement_alone():
    """PI takes no estimate: an observer gone wild (x2_hat = 1000 rad/s) changes none of its run.

    A law that needs the estimate refuses that one (beyond the velocity limit: 0 A).
    """
    plain = ClosedLoop(_ideal(controller='pi')).run()
    loop = ClosedLoop(_ideal(controller='pi'))
    update = loop.eso.update

    def wild(y, u):
        update(y, u)
        loop.eso.x2_hat = 1000.0

    loop.eso.update = wild
    trace = loop.run()
    assert np.array_equal(trace['current_a'], plain['current_a'])
    assert np.array_equal(trace['status'], plain['status']) and loop.assembly.refused == 0


def test_a_lost_command_the_observer_integrated_as_applied_is_corrected_exactly():
    """The drive missed u(1) and held u(0): an observer fed the held current is corrected.

    By default the observer integrates the command (as the ESO node, fed the controller's
    topic); fed the held current instead, the next estimate is made exact with dt theta1n
    (du) and the next command is the same. The raw x2_hat shows the difference.
    """
    scenario = _ideal()
    default, commanded, applied = (ClosedLoop(scenario) for _ in range(3))
    for loop in (default, commanded, applied):
        loop.step()
    default.step(command_lost=True)
    commanded.step(command_lost=True, eso_integrates_applied=False)
    applied.step(command_lost=True, eso_integrates_applied=True)
    d, c, a = default.step(), commanded.step(), applied.step()
    assert (d['x2_hat_rad_s'], d['current_a']) == (c['x2_hat_rad_s'], c['current_a'])
    assert (default.assembly.corrected, applied.assembly.corrected) == (0, 1)
    assert a['x2_hat_rad_s'] != c['x2_hat_rad_s']
    assert a['current_a'] == pytest.approx(c['current_a'], rel=1e-9)


def test_run_takes_the_samples_asked_and_returns_float_arrays():
    """run(n): n samples, not the scenario's; every field one float64 array (NaN fits in all)."""
    trace = ClosedLoop(_ideal()).run(7)
    assert set(trace) == set(TRACE_FIELDS)
    assert all(trace[f].dtype == np.float64 and trace[f].shape == (7,) for f in TRACE_FIELDS)
    assert list(trace['t_s']) == [k * 1e-3 for k in range(7)]


def test_run_stops_at_the_first_latched_sample_unless_told_not_to():
    """The controller latched (a 1 urad following-error limit): the trace ends at that sample."""
    loop = ClosedLoop(_ideal())
    loop.assembly.following_error_limit_rad = 1e-6
    trace = loop.run(30)
    assert len(trace['status']) < 30 and trace['status'][-1] == Status.LATCHED
    assert not np.any(trace['status'][:-1] == Status.LATCHED)
    loop = ClosedLoop(_ideal())
    loop.assembly.following_error_limit_rad = 1e-6
    assert len(loop.run(30, stop_on_divergence=False)['status']) == 30


def test_a_latched_loop_records_0_a_and_nan_terms_and_brakes_the_joint():
    """After the latch: 0 A (not NaN), every other term of the law NaN, the brake written.

    As the nodes do: the controller asks a safe stop, the drive's gate applies 0 A with the
    brake at once, and the joint is braked over the next interval; the law no longer runs.
    """
    loop = ClosedLoop(_ideal())
    loop.assembly.following_error_limit_rad = 1e-6
    record = loop.step()
    while record['status'] != Status.LATCHED:
        assert loop.joint.command[1] is False  # released while the law runs
        record = loop.step()
    assert loop.joint.command == (0.0, True)
    record = loop.step()
    assert record['status'] == Status.LATCHED and record['current_a'] == 0.0
    assert all(math.isnan(record[f]) for f in ControlOutput._fields if f != 'current_a')
    assert loop.joint.brake is True


def test_run_stops_where_the_measurement_stops_being_finite():
    """The joint's angle turns NaN after 5 samples: the trace ends with that sample."""
    loop = ClosedLoop(_ideal())
    loop.run(5)
    loop.plant.position_rad = float('nan')
    trace = loop.run(20)
    assert len(trace['t_s']) == 1 and np.isnan(trace['measured_position_rad'][0])
    assert len(loop.run(3, stop_on_divergence=False)['t_s']) == 3


@pytest.mark.parametrize('beyond, samples', [(0.0, 30), (1e-9, 11)])
def test_run_stops_only_beyond_the_divergence_error(beyond, samples):
    """|e| exactly DIVERGENCE_ERROR_RAD goes on; a step of it plus 1 nrad cuts the run there.

    PI on the loss-free joint at rest, latch off: 0 A and e = 0 until the step at 10 ms, where
    e = 0 - (-amplitude) exactly; PI then drives the joint towards it (|e| falls).
    """
    loop = ClosedLoop(_ideal(controller='pi', reference='step'))
    loop.assembly.reference = StepReference(-(DIVERGENCE_ERROR_RAD + beyond), start_s=0.01)
    loop.assembly.following_error_limit_rad = math.inf
    trace = loop.run(30)
    assert len(trace['error_rad']) == samples
    assert trace['error_rad'][10] == DIVERGENCE_ERROR_RAD + beyond
    assert np.all(np.abs(trace['error_rad'][11:]) < DIVERGENCE_ERROR_RAD)


def test_the_loop_gate_holds_each_command_with_its_sample_stamp():
    """After sample k the drive holds u(k) stamped t_k; a lost u(k+1) leaves u(k) and t_k held.

    The stamp is what the joint node reports as the applied command's (command_stamp_ns).
    """
    loop = ClosedLoop(_ideal())
    period = loop.period_ns
    loop.step()
    sent = loop.step()['current_a']
    held = loop.gate.hold(period)
    assert (held.current_a, held.command_stamp_ns, held.brake) == (sent, period, False)
    loop.step(command_lost=True)
    held = loop.gate.hold(2 * period)
    assert (held.current_a, held.command_stamp_ns) == (sent, period)


def test_the_loop_runs_the_scenarios_gains_and_stops_a_goal_at_its_deceleration():
    """The law gets the scenario's gains (not Table 4's), hold its trajectory settings' stop.

    A goal canceled 30 ms into its motion decelerates at the scenario's 40 rad/s^2 (the
    default is the joint's STOP_DECELERATION_RAD_S2), as the controller node's goals do.
    """
    from actuator_controller.goal_execution import Goal
    from actuator_controller.laws import PpNftsmcGains
    from actuator_controller.trajectory import Waypoints
    from actuator_controller.trajectory_settings import JointConstraints
    from actuator_core.limits import STOP_DECELERATION_RAD_S2
    from actuator_sim.scenarios import DRIVE_HOLD_SCENARIO, commanded

    (scenario,) = [s for s in commanded(0.2) if s.name == DRIVE_HOLD_SCENARIO]
    stop = JointConstraints(max_deceleration_on_cancel=40.0)
    scenario.trajectory = dataclasses.replace(scenario.trajectory, joints=(stop,))
    assert 40.0 != STOP_DECELERATION_RAD_S2 and scenario.gains != PpNftsmcGains()
    loop = ClosedLoop(scenario)
    assert loop.assembly.law.gains == scenario.gains
    wp = Waypoints(np.array([0.5]), np.array([[0.5]]))
    loop.submit_at(0, Goal('a', wp, scenario.trajectory.default_tolerances()))
    loop.cancel_at(30 * 1_000_000, 'a')
    trace = loop.run()
    after = trace['t_s'] >= 0.03
    peak = np.max(np.abs(trace['reference_acceleration_rad_s2'][after]))
    assert 0.99 * 40.0 <= peak <= 40.0 * (1 + 1e-9), peak


def test_a_batch_runs_each_element_as_the_single_run_from_its_first_sample():
    """A batch of 3: every state an array of three from the start, each column the single run."""
    single = ClosedLoop(_ideal()).run()
    loop = ClosedLoop(_ideal(), batch=3)
    assert np.shape(loop.plant.position_rad) == np.shape(loop.plant.velocity_rad_s) == (3,)
    batch = loop.run()
    for name in ('measured_position_rad', 'x2_hat_rad_s', 'current_a'):
        assert batch[name].shape == (50, 3)
        assert np.allclose(batch[name], single[name][:, None], rtol=1e-12, atol=0.0), name
