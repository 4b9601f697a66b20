# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Boundaries of compute_run_metrics (Tables 5 and 6) that the figures by hand leave open.

Each test kills mutants of actuator_core.metrics that survived ``make mutation``
(docs/mutation-report.md): the conversion of the inputs to double precision dropped, the
refusals' messages changed, the refusal of an empty run widened to a one-sample run.
"""

import math
import re

import numpy as np
import pytest

from actuator_core.metrics import compute_run_metrics


def _rms(values) -> float:
    """Root mean square in double precision, by hand: sqrt(sum(v^2) / n)."""
    values = [float(v) for v in values]
    return math.sqrt(sum(v * v for v in values) / len(values))


def test_a_single_sample_is_a_run():
    """One sample is the smallest run (only an empty one is refused): no duration, one sample."""
    m = compute_run_metrics(
        np.array([5.0]), np.array([-0.1]), np.array([2.0]), steady_state_start_s=5.0
    )
    assert (m.duration_s, m.samples, m.steady_window_s) == (0.0, 1, (5.0, 5.0))
    assert not m.diverged and m.bounds_kept and m.bounds_violations == 0
    # the one sample is in the window (t >= 5 s): every error figure is |e| = 0.1
    assert m.max_steady_error_rad == pytest.approx(0.1)
    assert m.rms_steady_error_rad == pytest.approx(0.1)
    assert m.rms_error_rad == pytest.approx(0.1)
    assert m.max_abs_current_a == 2.0 and m.rms_current_a == pytest.approx(2.0)


@pytest.mark.parametrize(
    't, e, u, message',
    [
        ([4.0, 5.0], [0.1], [1.0, 2.0], 't, error and current must be 1-D arrays of equal length'),
        ([4.0, 5.0], [0.1, 0.2], [1.0], 't, error and current must be 1-D arrays of equal length'),
        ([], [], [], 'a run needs at least one sample'),
    ],
)
def test_a_refused_run_is_told_exactly_why(t, e, u, message):
    """The whole message and nothing else: a refusal names what is wrong with the arrays."""
    with pytest.raises(ValueError, match=f'^{re.escape(message)}$'):
        compute_run_metrics(np.array(t), np.array(e), np.array(u))


# float32 samples, as a log with single-precision fields holds them; their double values are
# exact, but float32 arithmetic on them rounds (float32 eps ~ 6e-8, far above rel=1e-12).
T32 = np.array([0.1, 0.2, 0.3], dtype=np.float32)
E32 = np.array([0.1, -0.2, 0.3], dtype=np.float32)
U32 = np.array([0.7, -1.3, 2.9], dtype=np.float32)
V32 = np.array([0.3, -0.7, 1.1], dtype=np.float32)
D32 = np.array([1.7, -2.3, 0.9], dtype=np.float32)


def _run32(**kw):
    args = dict(t=T32, error=E32, current=U32, steady_state_start_s=0.15)
    args.update(kw)
    return compute_run_metrics(**args)


def test_the_duration_of_float32_stamps_is_taken_in_double_precision():
    """The stamps are made double before t[-1] - t[0]: a float32 difference rounds the duration."""
    m = _run32()
    expected = float(T32[2]) - float(T32[0])  # 0.2 up to the float32 rounding of the stamps
    assert m.duration_s == pytest.approx(expected, rel=1e-12, abs=0.0)
    assert float(T32[2] - T32[0]) != pytest.approx(expected, rel=1e-12, abs=0.0)


def test_the_error_figures_of_a_float32_error_are_taken_in_double_precision():
    """The error is made double before its RMS (whole run and steady window, t >= 0.15 s)."""
    m = _run32()
    assert m.rms_error_rad == pytest.approx(_rms(E32), rel=1e-12, abs=0.0)
    assert m.rms_steady_error_rad == pytest.approx(_rms(E32[1:]), rel=1e-12, abs=0.0)
    assert m.max_steady_error_rad == float(np.float32(0.3))


def test_the_current_figures_of_a_float32_current_are_taken_in_double_precision():
    """The current is made double before its RMS; its largest |u| is the float32 value itself."""
    m = _run32()
    assert m.rms_current_a == pytest.approx(_rms(U32), rel=1e-12, abs=0.0)
    assert m.max_abs_current_a == float(np.float32(2.9))


def test_the_estimate_errors_given_in_float32_are_taken_in_double_precision():
    """Both estimate errors are made double before their RMS."""
    m = _run32(velocity_estimate_error=V32, disturbance_estimate_error=D32)
    assert m.rms_velocity_estimate_error_rad_s == pytest.approx(_rms(V32), rel=1e-12, abs=0.0)
    assert m.rms_disturbance_estimate_error_rad_s2 == pytest.approx(_rms(D32), rel=1e-12, abs=0.0)


@pytest.mark.parametrize('values', [U32, V32, D32, E32, E32[1:]])
def test_the_float32_references_of_these_tests_do_round(values):
    """The RMS of each float32 input taken in float32 is off its double value by > rel 1e-12."""
    single = float(np.sqrt(np.mean(np.square(values))))
    assert single != pytest.approx(_rms(values), rel=1e-12, abs=0.0)


def test_an_infinite_current_is_reported_not_dropped():
    """A sample that commanded +-inf A shows in max |u| and RMS; only NaN (no command) is left out.

    Before, every non-finite current was dropped, so a run that sent inf A looked normal.
    """
    t = np.array([0.0, 1e-3, 2e-3, 3e-3])
    error = np.zeros(4)
    current = np.array([1.0, -np.inf, np.nan, 2.0])
    m = compute_run_metrics(t, error, current)
    assert m.max_abs_current_a == np.inf and m.rms_current_a == np.inf
    calm = compute_run_metrics(t, error, np.array([1.0, -2.0, np.nan, 2.0]))
    assert calm.max_abs_current_a == 2.0
    assert calm.rms_current_a == pytest.approx(np.sqrt((1.0 + 4.0 + 4.0) / 3.0), rel=1e-12)
