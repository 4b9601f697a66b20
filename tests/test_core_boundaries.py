# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The control core's references at their exact values (step edge, sine phase, overrides).

Written against surviving mutants of ``make mutation`` in the ROS-free core: the paper's
trajectories are pinned by the golden figures; these pin what the paper's cases do not run.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from actuator_controller.reference import SineReference, StepReference, make_reference


def test_step_is_zero_before_its_start_and_its_amplitude_from_it_on() -> None:
    """The edge belongs to the step (t >= start); velocity and acceleration are zero."""
    step = StepReference(amplitude_rad=0.3, start_s=0.5)
    assert step.sample(0.5 - 1e-9) == (0.0, 0.0, 0.0)
    assert step.sample(0.5) == (0.3, 0.0, 0.0)
    batch = step.sample(np.array([0.0, 0.5, 1.0]))
    np.testing.assert_array_equal(batch.position_rad, [0.0, 0.3, 0.3])
    np.testing.assert_array_equal(batch.velocity_rad_s, [0.0, 0.0, 0.0])


def test_sine_and_its_derivatives_at_a_quarter_period() -> None:
    """x1d = c + A sin(w t): at w t = pi/2 the value is c + A, velocity 0, acceleration -A w^2."""
    sine = SineReference(amplitude_rad=0.2, frequency_rad_s=4.0, offset_rad=0.1)
    s = sine.sample(math.pi / 8)
    assert s.position_rad == pytest.approx(0.3, abs=1e-15)
    assert s.velocity_rad_s == pytest.approx(0.0, abs=1e-15)
    assert s.acceleration_rad_s2 == pytest.approx(-0.2 * 16.0, rel=1e-15)
    assert sine.sample(0.0) == (0.1, 0.2 * 4.0, 0.0)


def test_make_reference_applies_the_overrides() -> None:
    """Amplitude and frequency given by name override the defaults of step and sine."""
    assert make_reference('step', amplitude_rad=0.7).sample(0.0).position_rad == 0.7
    sine = make_reference('sine', amplitude_rad=0.5, frequency_rad_s=3.0)
    assert (sine.amplitude_rad, sine.frequency_rad_s) == (0.5, 3.0)
    assert make_reference('sine').sample(0.0) == SineReference().sample(0.0)
