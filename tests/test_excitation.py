# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The identification run's reference: its bounds, smoothness, start, parameters and scenario."""

from __future__ import annotations

import math

import numpy as np
import pytest

from actuator_controller.excitation import FADE_S, ExcitationReference
from actuator_controller.reference import REFERENCE_KINDS, make_reference
from actuator_core import limits

DT = 1e-4


def _trace(ref: ExcitationReference, cycles: float = 1.0):
    t = np.arange(0.0, cycles * ref.cycle_s, DT)
    return t, ref.sample(t)


@pytest.mark.slow
@pytest.mark.parametrize(
    'ref',
    [
        ExcitationReference(),
        ExcitationReference(
            amplitude_rad=0.2,
            low_frequency_hz=1.0,
            high_frequency_hz=20.0,
            sweep_velocity_rad_s=1.0,
            acceleration_rad_s2=80.0,
        ),
    ],  # fmt: skip
)
def test_the_excitation_stays_inside_its_bounds(ref):
    t, (x, v, a) = _trace(ref)
    assert np.max(np.abs(x)) <= ref.amplitude_rad * (1 + 1e-6)
    assert np.max(np.abs(x)) >= 0.95 * ref.amplitude_rad  # and uses its room
    assert np.max(np.abs(v)) <= limits.EXCITATION_VELOCITY_RAD_S
    # on the plateaus the acceleration bound holds; the fades (quintic, FADE_S) add a little
    starts = [s for s, *_ in ref._segments[0]]
    in_fade = np.zeros(t.size, bool)
    for s, plateau, *_ in ref._segments[0]:
        in_fade |= ((t >= s) & (t < s + FADE_S)) | (
            (t >= s + plateau + FADE_S) & (t < s + plateau + 2 * FADE_S)
        )
    assert np.max(np.abs(a[~in_fade])) <= ref.acceleration_rad_s2 * (1 + 1e-6)
    assert np.max(np.abs(a)) <= 1.25 * ref.acceleration_rad_s2
    assert len(starts) == 4


@pytest.mark.slow
def test_the_excitation_starts_at_rest_and_is_twice_differentiable():
    ref = ExcitationReference()
    assert tuple(ref.sample(0.0)) == (0.0, 0.0, 0.0)
    t, (x, v, a) = _trace(ref, 2.0)
    # the derivatives it reports integrate to its angle and velocity (trapezoids of 0.1 ms)
    from scipy.integrate import cumulative_trapezoid

    assert np.max(np.abs(cumulative_trapezoid(v, t, initial=0.0) - x)) < 1e-6
    assert np.max(np.abs(cumulative_trapezoid(a, t, initial=0.0) - v)) < 1e-3
    assert np.max(np.abs(np.diff(a))) < 5.0  # no step in the acceleration (jerk bounded)
    # every segment passes through rest at 0 between its fades
    for start, *_ in ref._segments[0]:
        assert np.allclose(ref.sample(start), 0.0, atol=1e-12)


@pytest.mark.slow
def test_the_sweeps_hold_their_speeds_both_ways():
    ref = ExcitationReference(sweep_velocity_rad_s=2.0)
    t, (x, v, a) = _trace(ref)
    for speed in (0.5, 1.0, 2.0):
        for direction in (1.0, -1.0):
            held = np.isclose(v, direction * speed, atol=1e-9) & (a == 0.0)
            assert held.sum() * DT > 0.3, (speed, direction)


def test_bad_excitation_parameters_are_refused():
    with pytest.raises(ValueError, match=r'high_frequency_hz / low_frequency_hz must be in'):
        ExcitationReference(low_frequency_hz=2.0, high_frequency_hz=1.0)
    with pytest.raises(ValueError) as err:
        ExcitationReference(amplitude_rad=0.1, sweep_velocity_rad_s=4.0)
    assert str(err.value) == (
        'excitation: a sweep at 4 rad/s turning at 157.186 rad/s^2 overshoots by v^2/a = 0.102 '
        'rad, more than half of amplitude_rad = 0.1: lower the speed'
    )
    with pytest.raises(ValueError) as err:
        ExcitationReference(acceleration_rad_s2=700.0)
    assert str(err.value).startswith(
        'ExcitationReference.acceleration_rad_s2 = 700.0 is outside its valid range (0, 628.743] '
        'rad/s^2: '
    )


@pytest.mark.slow
def test_the_reference_kind_and_the_scenario():
    from actuator_sim.params_yaml import all_scenarios

    assert 'excitation' in REFERENCE_KINDS
    custom = ExcitationReference(amplitude_rad=0.3)
    assert make_reference('excitation') == ExcitationReference()
    assert make_reference('excitation', excitation=custom) is custom
    scenario = all_scenarios()['excitation']
    assert scenario.reference == 'excitation' and scenario.controller == 'pp_nftsmc_eso'
    cycles = scenario.duration_s / ExcitationReference().cycle_s
    assert 2.0 <= cycles < 2.0 + 0.1 / ExcitationReference().cycle_s + 1e-9
    assert math.isclose(ExcitationReference().acceleration_rad_s2, 0.25 * limits.THETA1N * 20.0)
