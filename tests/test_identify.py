# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Identification on joints of known truth (identify_helpers): estimates, intervals, refusals.

The synthetic joints are of the model's own family, so every parameter has an exact truth and
its 95 % interval must hold it; one test uses the suite's plant (eq. (1), (6), (42)) whose seal
friction is outside the family, where theta1 must still be found.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from actuator_analysis import identify as idf
from actuator_analysis.identify_heldout import simulate
from actuator_analysis.identify_joint import identify
from identify_helpers import DT_S, Truth, synthetic_joint

pytestmark = pytest.mark.slow


@pytest.fixture(scope='module')
def drag_joint():
    """Run a joint with Coulomb, viscous and drag friction and a constant load."""
    return synthetic_joint(Truth())


def _covers(result, name, truth):
    low, high = result.interval(name)
    return low <= truth <= high


def test_every_estimate_of_a_drag_joint_is_in_its_interval(drag_joint):
    truth = drag_joint.truth
    result = identify([drag_joint.record()])
    assert result.model == 'drag'
    for name in idf.PARAMETERS['drag']:
        assert _covers(result, name, getattr(truth, name)), (name, result.chosen.as_dict()[name])
    low, high = result.interval('theta1')
    assert high - low < 0.01 * truth.theta1  # +-0.5 %: the excitation determines theta1
    assert result.held_out.velocity_r2 > 0.999
    assert result.held_out.position_rms_rad < 1e-2


@pytest.mark.parametrize(
    'truth, model',
    [
        (Truth(drag_per_rad=0.0), 'coulomb_viscous'),
        (Truth(drag_per_rad=0.0, stribeck_rad_s2=10.0, stribeck_velocity_rad_s=1.0), 'stribeck'),
    ],
)
def test_the_friction_model_is_the_one_the_data_supports(truth, model):
    """The model of the data is chosen, and its estimates are the truth's.

    To a tolerance rather than by the intervals: on these noise-free joints of the model's own
    family the intervals are 0.01-0.3 % wide, and the Coulomb step at the velocity reversals
    leaves a bias of 0.02-0.07 % in theta1 beyond the filter guard (``identify``'s docstring),
    0.2-0.3 % in theta2 and the Coulomb friction with Stribeck's term.
    """
    result = identify([synthetic_joint(truth).record()])
    assert result.model == model
    for name in idf.PARAMETERS[model]:
        expected = getattr(truth, name)
        tolerance = 5e-3 if name == 'offset_rad_s2' else 2e-2 * abs(expected)
        if name in ('theta2', 'coulomb_rad_s2'):
            tolerance = 5e-3 * abs(expected)
        if name == 'theta1':
            tolerance = 1e-3 * abs(expected)
        assert result.value(name) == pytest.approx(expected, abs=tolerance), name


def test_two_records_identify_as_one(drag_joint):
    """Records split at a gap: the blocks of both are fitted, the offset shared."""
    rec = drag_joint.record()
    half = len(rec.position_rad) // 2
    parts = [
        dataclasses.replace(rec, position_rad=x, current_a=i, at_limit=m)
        for x, i, m in zip(
            np.split(rec.position_rad, [half]),
            np.split(rec.current_a, [half]),
            np.split(rec.at_limit, [half]),
        )
    ]
    whole, split = identify([rec]), identify(parts)
    assert split.figures['records'] == 2
    assert split.figures['held_out_blocks'] == 2  # one per half: 7 s each, block 3 held out
    assert abs(split.value('theta1') / whole.value('theta1') - 1.0) < 1e-3


def test_theta1_of_the_suites_plant_is_found_despite_its_exponential_seal():
    """The plant of eq. (1), stirring loss (6), seal friction (42) at 1000 m, PD-controlled."""
    from actuator_controller.excitation import ExcitationReference
    from actuator_plant.model import JointPlant, PlantParameters
    from identify_helpers import LOOP_DAMPING, LOOP_RAD_S, LOOP_THETA1

    params = PlantParameters(with_drift=False, with_external_torque=False)
    plant, ref = JointPlant(params, DT_S), ExcitationReference()
    n = 14000
    y, held = np.empty(n), np.empty(n)
    current, before = 0.0, 0.0
    res = 2 * np.pi / 2**16
    for k in range(n):
        if k:
            plant.step(current)
        held[k] = current
        y[k] = round(plant.position_rad / res) * res
        r = ref.sample(k * DT_S)
        speed = (y[k] - before) / DT_S if k else 0.0
        before = y[k]
        wanted = (
            r.acceleration_rad_s2
            + LOOP_RAD_S**2 * (r.position_rad - y[k])
            + 2 * LOOP_DAMPING * LOOP_RAD_S * (r.velocity_rad_s - speed)
        )
        current = wanted / LOOP_THETA1
    result = identify([idf.Record(DT_S, y, held, np.zeros(n, bool))])
    theta1 = params.nominal.theta1n
    assert _covers(result, 'theta1', theta1)
    assert abs(result.value('theta1') / theta1 - 1.0) < 2e-3
    assert result.model == 'drag'  # eq. (42) grows faster than linearly with the speed


def test_the_simulation_is_the_model():
    """simulate() integrates q'' = theta1 i + theta2 v - f(v) + c: a constant current from rest."""
    estimate = np.array([20.0, -5.0, 10.0, 1.0, 0.0])  # theta1, theta2, fc, c, drag
    q, v = simulate('drag', estimate, 0.0, 0.0, np.full(3000, 1.0), DT_S)
    # steady state: 0 = 20 - 5 v - 10 + 1 -> v = 2.2 rad/s, approached with time constant 0.2 s
    assert v[-1] == pytest.approx(2.2, rel=1e-5)
    assert v[200] == pytest.approx(2.2 * (1 - np.exp(-1.0)), rel=1e-3)
    assert q[-1] == pytest.approx(2.2 * 3.0 - 2.2 * 0.2 * (1 - np.exp(-15.0)), rel=1e-4)


# --- refusals -------------------------------------------------------------------------------


def test_a_non_finite_sample_is_refused(drag_joint):
    rec = drag_joint.record('run')
    angle = rec.position_rad.copy()
    angle[500] = np.nan
    with pytest.raises(idf.RefusedData) as err:
        identify([dataclasses.replace(rec, position_rad=angle)])
    assert str(err.value) == (
        'run: 1 angle or current samples are not finite (NaN or inf): the joint or the bag '
        'reported no value there'
    )


def test_a_slow_run_at_nearly_constant_speed_is_refused():
    """A slow back-and-forth (0.63 rad/s at most, 0.2 rad/s^2): friction shows, theta1 does not."""
    from actuator_controller.reference import ReferenceSample

    class Slow:
        def sample(self, t):
            w = 2.0 * np.pi * 0.05
            return ReferenceSample(
                2.0 * (1 - np.cos(w * t)), 2.0 * w * np.sin(w * t), 2.0 * w * w * np.cos(w * t)
            )

    with pytest.raises(idf.RefusedData) as err:
        identify([synthetic_joint(reference=Slow(), duration_s=20.0).record()])
    text = str(err.value)
    assert text.startswith('the joint hardly accelerated (acceleration RMS ')
    assert text.endswith(
        ' rad/s^2, below 5): a run at constant speed or at rest shows friction, not theta1; '
        'record the excitation scenario'
    )


def test_a_run_at_the_current_limit_is_refused():
    run = synthetic_joint(current_limit_a=4.0)  # the excitation needs about 8 A here
    with pytest.raises(idf.RefusedData) as err:
        identify([run.record()])
    share = 100 * np.mean(run.at_limit)
    assert str(err.value) == (
        f'the current was at its limit in {share:.1f} % of the samples (more than 1 %): there the '
        "joint follows the drive's limit, not the model; lower the excitation "
        '(excitation.acceleration_rad_s2, excitation.amplitude_rad)'
    )


def test_motion_one_way_is_refused():
    from actuator_controller.reference import ReferenceSample

    class Forward:
        def sample(self, t):
            return ReferenceSample(
                0.5 * t + 0.02 * np.sin(20 * t), 0.5 + 0.4 * np.cos(20 * t), -8 * np.sin(20 * t)
            )

    with pytest.raises(idf.RefusedData, match=r'^the joint moved one way only \(100 % of the '):
        identify([synthetic_joint(reference=Forward()).record()])


def test_too_short_a_run_is_refused():
    with pytest.raises(idf.RefusedData) as err:
        identify([synthetic_joint(duration_s=6.0).record()])
    assert str(err.value) == (
        'too little data: 5.8 s of usable samples in 5 training and 1 held-out blocks of 1 s; at '
        'least 8 s, 6 and 2 are needed (record the excitation scenario for 20 s or more)'
    )


def test_a_reversed_current_is_refused():
    """A drive whose current sign is opposite to the recorded one: theta1 comes out negative."""
    rec = synthetic_joint().record()
    with pytest.raises(idf.RefusedData, match=r'^theta1 = -2.* is not positive: the current'):
        identify([dataclasses.replace(rec, current_a=-rec.current_a)])


def test_a_drifting_joint_is_refused_or_given_a_wide_interval():
    """theta1 drifting by +-30 %: no single theta1 fits; the interval says so, or it is refused."""
    with pytest.raises(idf.RefusedData, match=r'^theta1 is not determined: 2.* more than \+-10 %'):
        identify([synthetic_joint(Truth(theta1_drift=(0.3, 0.94))).record()])
    steady = identify([synthetic_joint(Truth(theta1_drift=(0.0, 0.94))).record()])
    drifting = identify([synthetic_joint(Truth(theta1_drift=(0.05, 0.94))).record()])
    width = [np.diff(r.interval('theta1'))[0] for r in (steady, drifting)]
    assert width[1] > 20 * width[0]
    assert drifting.held_out.velocity_r2 < steady.held_out.velocity_r2
