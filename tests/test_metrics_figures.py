# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Every figure of compute_run_metrics (Tables 5 and 6) on runs small enough to work by hand.

``make mutation`` left 83 mutants of actuator_core.metrics alive (docs/mutation-report.md): no
test compared the figures themselves. Each one here is computed by hand from three samples.
"""

import math
import warnings

import numpy as np
import pytest

from actuator_core.limits import DIVERGENCE_ERROR_RAD
from actuator_core.metrics import RunMetrics, compute_run_metrics

T = np.array([4.0, 5.0, 6.0])
E = np.array([0.3, -0.2, 0.1])
U = np.array([1.0, -3.0, math.nan])


def _run(**kw):
    args = dict(t=T, error=E, current=U, steady_state_start_s=5.0)
    args.update(kw)
    return compute_run_metrics(**args)


def test_every_figure_of_a_run_inside_its_bounds_by_hand():
    m = _run(
        lower_bound=np.array([-0.4, -0.3, -0.5]),
        upper_bound=np.array([0.4, 0.4, 0.2]),
        saturated=np.array([True, False, True]),
        velocity_estimate_error=np.array([1.0, -1.0, 1.0]),
        disturbance_estimate_error=np.array([2.0, -2.0, 2.0]),
    )
    assert (m.duration_s, m.samples, m.steady_window_s) == (2.0, 3, (5.0, 6.0))
    assert not m.diverged
    assert m.max_steady_error_rad == pytest.approx(0.2)
    assert m.rms_steady_error_rad == pytest.approx(math.sqrt((0.04 + 0.01) / 2))
    assert m.rms_error_rad == pytest.approx(math.sqrt((0.09 + 0.04 + 0.01) / 3))
    assert m.max_abs_current_a == 3.0  # the NaN current is left out
    assert m.rms_current_a == pytest.approx(math.sqrt((1.0 + 9.0) / 2))
    assert m.saturated_fraction == pytest.approx(2.0 / 3.0)
    assert m.bounds_kept and m.bounds_violations == 0
    assert m.rms_velocity_estimate_error_rad_s == pytest.approx(1.0)
    assert m.rms_disturbance_estimate_error_rad_s2 == pytest.approx(2.0)
    assert m.as_dict()['steady_window_s'] == (5.0, 6.0)
    assert RunMetrics(**m.as_dict()) == m


def test_an_error_on_a_bound_violates_it():
    # -0.2 on the lower bound -0.2 and 0.1 on the upper bound 0.1: both outside (strict, eq. 8)
    m = _run(lower_bound=np.array([-0.4, -0.2, -0.5]), upper_bound=np.array([0.4, 0.4, 0.1]))
    assert m.bounds_violations == 2 and not m.bounds_kept


def test_without_bounds_saturation_or_estimates_the_defaults_say_so():
    m = _run(lower_bound=np.array([0.0, 0.0, 0.0]))  # one bound only: no envelope to judge
    assert m.bounds_violations == 0 and m.bounds_kept
    assert m.saturated_fraction == 0.0
    assert m.rms_velocity_estimate_error_rad_s is None
    assert m.rms_disturbance_estimate_error_rad_s2 is None


@pytest.mark.parametrize('bad', [math.nan, math.inf, DIVERGENCE_ERROR_RAD * 1.001])
def test_a_diverged_run_has_no_error_figures(bad):
    m = _run(error=np.array([0.3, bad, 0.1]))
    assert m.diverged and not m.bounds_kept
    assert math.isnan(m.max_steady_error_rad)
    assert math.isnan(m.rms_steady_error_rad) and math.isnan(m.rms_error_rad)
    assert m.max_abs_current_a == 3.0  # the current figures stand


def test_an_error_at_the_divergence_limit_is_not_divergence():
    m = _run(error=np.array([0.3, -DIVERGENCE_ERROR_RAD, 0.1]))
    assert not m.diverged and m.max_steady_error_rad == DIVERGENCE_ERROR_RAD


def test_a_run_ending_before_its_steady_window_has_nan_steady_figures_and_no_warning():
    with warnings.catch_warnings():
        warnings.simplefilter('error')  # the mean of an empty window would warn
        m = _run(steady_state_start_s=7.0, current=np.array([math.nan] * 3))
    assert math.isnan(m.max_steady_error_rad) and math.isnan(m.rms_steady_error_rad)
    assert m.rms_error_rad == pytest.approx(math.sqrt((0.09 + 0.04 + 0.01) / 3))
    assert math.isnan(m.max_abs_current_a) and math.isnan(m.rms_current_a)
    assert m.steady_window_s == (7.0, 6.0)


def test_the_first_sample_at_the_window_start_is_in_the_window():
    m = _run(steady_state_start_s=4.0)
    assert m.max_steady_error_rad == pytest.approx(0.3)


@pytest.mark.parametrize(
    't, e, u',
    [
        (T, E[:2], U),
        (T, E, U[:2]),
        (T.reshape(3, 1), E.reshape(3, 1), U.reshape(3, 1)),
        (np.array([]), np.array([]), np.array([])),
    ],
)
def test_arrays_of_unequal_length_or_none_are_refused(t, e, u):
    with pytest.raises(ValueError, match='1-D arrays of equal length|at least one sample'):
        compute_run_metrics(t, e, u)
