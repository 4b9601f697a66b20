# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Boundaries of the envelope (ppf, eq. (8)-(12)) and the observer's gains (eq. (15)-(16)).

Each test kills mutants that survived ``make mutation`` (docs/mutation-report.md): a strict
inequality made loose, a division made a product, an argument dropped.
"""

import math

import numpy as np
import pytest

from actuator_controller.ppf import BOUNDARY_MARGIN, PrescribedPerformance, transform_error
from actuator_eso.observer import EsoGains, ExtendedStateObserver, input_current_correction


def test_a_constant_envelope_is_allowed_and_a_growing_one_refused():
    assert PrescribedPerformance(rho0_rad=0.1, rho_inf_rad=0.1).rho(3.0) == pytest.approx(0.1)
    with pytest.raises(ValueError, match='must not exceed rho0_rad'):
        PrescribedPerformance(rho0_rad=0.1, rho_inf_rad=0.2)


def test_the_restarted_envelope_divides_by_the_narrower_scale():
    ppf = PrescribedPerformance(lower_scale=0.5, upper_scale=2.0, restart_margin=2.0)
    assert ppf.restart_rho0(-0.2) == pytest.approx(2.0 * 0.2 / 0.5)  # 0.8, above rho0 = 0.25
    assert ppf.restart_rho0(0.01) == ppf.rho0_rad  # a small error keeps rho0


@pytest.mark.parametrize('e_over_rho', [-1.0, 1.0])
def test_an_error_on_a_bound_is_outside(e_over_rho):
    ppf = PrescribedPerformance()
    rho = 0.25
    assert not transform_error(e_over_rho * rho, rho, ppf).inside
    assert transform_error(0.999 * e_over_rho * rho, rho, ppf).inside


def test_outside_the_band_z_is_that_of_the_clamp_a_margin_of_the_band_inside():
    ppf = PrescribedPerformance(lower_scale=1.0, upper_scale=1.0)
    rho = 0.25
    band = ppf.lower_scale + ppf.upper_scale
    eps_c = ppf.upper_scale - BOUNDARY_MARGIN * band
    expected = 0.5 * math.log((eps_c + ppf.lower_scale) / (ppf.upper_scale - eps_c))
    out = transform_error(2.0 * rho, rho, ppf)
    assert out.z == pytest.approx(expected, rel=1e-12) and not out.inside


def test_l1_l2_equal_to_l3_is_refused_as_not_hurwitz():
    with pytest.raises(ValueError, match='l1\\*l2 must exceed l3'):
        EsoGains(l1=1.0, l2=2.0, l3=2.0)
    EsoGains(l1=1.0, l2=2.0, l3=1.999)


def test_gains_from_bandwidth_put_the_three_poles_at_c_omega0():
    gains = EsoGains.from_bandwidth(40.0, 4.0, theta1n=900.0, theta2n=-2.0)
    assert (gains.omega0_rad_s, gains.l1, gains.l2, gains.l3) == (40.0, 12.0, 48.0, 64.0)
    assert (gains.theta1n, gains.theta2n) == (900.0, -2.0)
    # s^3 + l1 w s^2 + l2 w^2 s + l3 w^3 = (s + c w)^3
    beta = gains.beta
    assert np.allclose(np.roots([1.0, *beta]), -160.0, atol=0.05)


def test_no_current_change_corrects_nothing():
    gains = EsoGains()
    assert input_current_correction(0.0, 3, 1e-3, gains) == (0.0, 0.0, 0.0)
    d = input_current_correction(1.0, 0, 1e-3, gains)
    assert d == (0.0, 1e-3 * gains.theta1n, 0.0)


@pytest.mark.parametrize('dt_s', [0.0, -1e-3, math.inf, math.nan])
def test_the_observer_refuses_a_step_that_is_not_finite_and_positive(dt_s):
    with pytest.raises(ValueError, match='dt_s must be finite and > 0'):
        ExtendedStateObserver(EsoGains(), dt_s)
