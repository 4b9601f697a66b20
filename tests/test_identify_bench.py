# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""identify_bench's parts without the nodes: the draws, their joint files, truth and verdicts."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from actuator_bench.identify_bench import (
    DRAW_RANGES,
    Draw,
    draw_joints,
    summarise,
    tracking,
)
from actuator_core import limits
from actuator_core.params import build
from actuator_plant.model import PlantParameters, derive_constants, working_condition
from actuator_sim.params_yaml import dotted


def test_draws_stay_in_their_ranges_and_repeat_with_the_seed():
    draws = draw_joints(200, seed=3)
    assert draws == draw_joints(200, seed=3) and draws != draw_joints(200, seed=4)
    factors = {
        'inertia_factor': [d.inertia_kg_m2 / limits.NOMINAL_INERTIA_KG_M2 for d in draws],
        'torque_constant_factor': [
            d.torque_constant_nm_a / limits.NOMINAL_TORQUE_CONSTANT_NM_A for d in draws
        ],
        'viscous_factor': [d.viscous_nm_s_rad / limits.NOMINAL_VISCOUS_NM_S_RAD for d in draws],
        'seal_base_nm': [d.seal_base_nm for d in draws],
        'depth_m': [d.depth_m for d in draws],
        'encoder_bits': [d.encoder_bits for d in draws],
    }
    for name, values in factors.items():
        low, high = DRAW_RANGES[name]
        assert low <= min(values) and max(values) <= high, name
        assert max(values) - min(values) > 0.8 * (high - low), name  # the range is used
    assert set(factors['encoder_bits']) == set(range(14, 21))


def test_the_joint_file_gives_the_plant_node_the_drawn_joint():
    """The plant node builds PlantParameters from its parameters, then the working condition."""
    draw = draw_joints(1, seed=9)[0]
    values = dotted(draw.joint_file()['actuator_plant']['ros__parameters'])
    params = build(PlantParameters, values)
    params = dataclasses.replace(
        params,
        condition=working_condition(
            values['working_condition'], values['depth_m'], params.condition
        ),
    )
    assert params == draw.plant
    assert values['encoder.counts_per_rev'] == 2**draw.encoder_bits


def test_the_truth_is_the_models_linear_terms():
    draw = Draw(0, 4.0e-5, 0.1, 2.0e-5, 1.0, 0.0, 16)
    truth = draw.truth()
    assert truth['theta1'] == pytest.approx(0.1 / (4.0e-5 * 100.0))
    assert truth['theta2_motor'] == pytest.approx(-0.5)
    stirring = derive_constants(draw.plant).stirring_coefficient_nm_s_rad  # k mu, 0 m, 2 degC
    assert stirring > 0.0
    assert truth['theta2'] == pytest.approx(-0.5 - stirring / 4.0e-5)


def test_the_verdicts_follow_the_targets():
    def row(error, covered, ratio):
        return {
            'draw': {'index': 0}, 'error': None, 'theta1_error': error, 'theta1_covered': covered,
            'theta2_error': 0.1, 'theta2_covered': False, 'held_out': {'velocity_r2': 0.99},
            'tracking_ratio': ratio,
        }  # fmt: skip

    good = [row(0.01, True, 1.0)] * 9 + [row(0.09, False, 1.3)]
    assert all(summarise(good)['targets'].values())
    bad = [row(0.01, True, 1.0)] * 8 + [row(0.11, False, 1.3)] * 2
    verdicts = summarise(bad)['targets']
    assert not verdicts['theta1 worst error <= 10 %']
    assert not verdicts['intervals cover theta1 in >= 90 %']
    assert verdicts['theta1 median error <= 5 %'] and verdicts['tracking ratio median <= 1.2']
    failed = summarise([{'draw': {'index': 3}, 'error': 'refused: ...'}])
    assert failed['identified'] == 0 and failed['refused_or_failed'] == [(3, 'refused: ...')]


@pytest.mark.slow
def test_tracking_runs_the_fast_case_with_each_nominal_model():
    draws = draw_joints(2, seed=46)
    true = {
        'theta1': np.array([d.truth()['theta1'] for d in draws]),
        'theta2': np.array([d.truth()['theta2_motor'] for d in draws]),
    }
    wrong = {'theta1': true['theta1'] * 3.0, 'theta2': true['theta2']}
    with_true, with_wrong = tracking(draws, true), tracking(draws, wrong)
    assert np.all(with_true < 3e-3)  # the paper's fast case: below a few mrad
    assert np.all(with_wrong > with_true)  # a b0 three times the joint's tracks worse
