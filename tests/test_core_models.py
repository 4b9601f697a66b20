# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Plant, loss models, ESO and PPF.

The ROS-free core against hand calculations and known signals.
"""

import dataclasses
import math

import numpy as np
import pytest

from actuator_controller.ppf import PrescribedPerformance, inverse_transform, transform_error
from actuator_eso.observer import (
    EsoGains,
    ExtendedStateObserver,
    eso_step,
    input_current_correction,
)
from actuator_plant.model import (
    CONDITION_CHOICES,
    GRAVITY_M_S2,
    SEAWATER_DENSITY_KG_M3,
    JointPlant,
    PlantParameters,
    WorkingCondition,
    braked_step,
    derive_constants,
    disturbance_parts,
    joint_forces,
    working_condition,
)
from actuator_plant.oil import (
    MotorGeometry,
    OilProperties,
    dynamic_viscosity_pa_s,
    kinematic_viscosity_m2_s,
    stirring_geometry_constant_m3,
)


def test_walther_passes_through_its_two_data_points():
    oil = OilProperties()
    assert kinematic_viscosity_m2_s(40.0, oil) == pytest.approx(22.0e-6, rel=1e-9)
    assert kinematic_viscosity_m2_s(100.0, oil) == pytest.approx(4.3e-6, rel=1e-9)


def test_viscosity_at_paper_conditions_by_hand():
    oil = OilProperties()
    # Walther by hand at 2 degC: A, B through (40 degC, 22) and (100 degC, 4.3).
    w40, w100 = math.log10(math.log10(22.7)), math.log10(math.log10(5.0))
    b = (w40 - w100) / (math.log10(373.15) - math.log10(313.15))
    a = w40 + b * math.log10(313.15)
    nu2 = 10 ** (10 ** (a - b * math.log10(275.15))) - 0.7
    rho2 = 870.0 / (1.0 + 6.5e-4 * (2.0 - 15.0))
    alpha = 1.0 / (4.49e7 + 1.6e-2 * 10.0)
    assert dynamic_viscosity_pa_s(2.0, 10.0e6, oil) == pytest.approx(
        rho2 * nu2 * 1e-6 * math.exp(alpha * 10.0e6)
    )
    # Lab: no pressure, so exp(alpha P) = 1, and mu0(25 degC) is about 36 mPa s.
    assert dynamic_viscosity_pa_s(25.0, 0.0, oil) == pytest.approx(0.0365, rel=0.02)
    assert dynamic_viscosity_pa_s(2.0, 10.0e6, oil) > dynamic_viscosity_pa_s(2.0, 0.0, oil)


def test_stirring_geometry_constant_by_hand():
    k = stirring_geometry_constant_m3(MotorGeometry())
    flank = math.pi * 0.0155 * 0.0375**3 / (4 * 0.0003)
    disk = math.pi * (0.063**4 - 0.0375**4) / (32 * 0.038)
    assert k == pytest.approx(flank + disk, rel=1e-12)
    with pytest.raises(ValueError, match='d2'):
        MotorGeometry(
            rotor_end_diameter_m=0.063, housing_end_diameter_m=0.0375
        )  # Table 3 as printed


def test_losses_at_one_state_by_hand():
    params = PlantParameters(condition=WorkingCondition.deep_sea())
    c = derive_constants(params)
    t, v, u = 0.7, 2.0, 3.0
    f = joint_forces(t, v, c)
    k_mu = stirring_geometry_constant_m3(MotorGeometry()) * dynamic_viscosity_pa_s(
        2.0, 10e6, OilProperties()
    )
    assert f.stirring_torque_nm == pytest.approx(k_mu * 100.0 * v)  # (6), rotor speed N q'
    assert f.external_torque_nm == pytest.approx(
        20.0 * (1 + 0.5 * math.sin(0.5 * math.pi * t))
    )  # (40)
    assert f.seal_torque_nm == pytest.approx(
        1 + math.exp(0.3591 * v) + math.exp(0.1504 * 10.0)
    )  # (42)
    assert f.inertia_kg_m2 == pytest.approx(
        3.34e-5 * (1 + 0.2 * math.sin(0.5 * math.pi * t))
    )  # (41)
    parts = disturbance_parts(t, v, u, c)
    assert parts.disturbance_rad_s2 == pytest.approx(
        parts.parametric_rad_s2 + parts.stirring_rad_s2 + parts.external_rad_s2 + parts.seal_rad_s2
    )
    # (1) solved for q'' equals the nominal model (5) plus d.
    j, kt, kb = f.inertia_kg_m2, f.torque_constant_nm_a, f.viscous_coefficient_nm_s_rad
    qdd = (
        kt * u
        - kb * 100 * v
        - f.stirring_torque_nm
        - (f.external_torque_nm + f.seal_torque_nm) / 100
    ) / (j * 100)
    assert parts.acceleration_rad_s2 == pytest.approx(qdd)
    # Seal friction range of Fig. 4 at rest-limit: 3 N m in the lab, 6.5 N m in the deep sea.
    lab = derive_constants(PlantParameters(condition=WorkingCondition.lab()))
    assert joint_forces(0.0, 1e-12, lab).seal_torque_nm == pytest.approx(3.0)


def test_depth_gives_hydrostatic_pressure():
    assert WorkingCondition.at_depth(1000.0).pressure_pa == pytest.approx(10.05e6, rel=1e-3)
    with pytest.raises(ValueError, match='depth_m'):
        WorkingCondition.at_depth(-5.0)
    with pytest.raises(ValueError, match='pressure_pa'):
        WorkingCondition(pressure_pa=float('nan'), temperature_c=2.0)


def test_ideal_plant_matches_closed_form_with_current_held():
    params = PlantParameters().ideal()
    plant = JointPlant(params, 1e-3)
    th1, th2 = params.nominal.theta1n, params.nominal.theta2n
    u = 2.0
    for _ in range(500):
        plant.step(u)
    t = 0.5
    v = th1 * u / th2 * (math.exp(th2 * t) - 1.0)
    q = th1 * u / th2 * ((math.exp(th2 * t) - 1.0) / th2 - t)
    assert plant.velocity_rad_s == pytest.approx(v, rel=1e-9)
    assert plant.position_rad == pytest.approx(q, rel=1e-9)
    assert plant.time_s == pytest.approx(0.5)


@pytest.mark.slow
def test_full_plant_converges_with_substeps():
    coarse, fine = (
        JointPlant(PlantParameters(substeps=4), 1e-3),
        JointPlant(PlantParameters(substeps=64), 1e-3),
    )
    for k in range(2000):
        u = 5.0 * math.sin(8.0 * k * 1e-3)
        coarse.step(u)
        fine.step(u)
    # The joint falls about 4.7 rad under the external torque, reversing through the seal's
    # sign(q') discontinuity; 4 substeps stay within 1e-4 of the travel.
    assert abs(coarse.position_rad - fine.position_rad) < 1e-4 * abs(fine.position_rad)
    assert np.isfinite(coarse.velocity_rad_s)


def test_eso_gains_follow_bandwidth_parametrisation_and_refuse_non_hurwitz():
    g = EsoGains.from_bandwidth(60.0)
    assert (g.l1, g.l2, g.l3) == (15.0, 75.0, 125.0)
    poles = np.roots([1.0, g.beta[0], g.beta[1], g.beta[2]])
    assert np.allclose(poles, -300.0, atol=1e-2)
    with pytest.raises(ValueError, match='Hurwitz'):
        EsoGains(l1=1.0, l2=1.0, l3=5.0)
    with pytest.raises(ValueError, match='omega0_rad_s'):
        EsoGains(omega0_rad_s=-1.0)


def test_eso_converges_on_a_known_signal():
    """Truth.

    x'' = theta1n u + theta2n x' + d with a slowly varying d; the ESO must find x' and d.
    """
    gains = EsoGains()
    dt = 1e-4
    eso = ExtendedStateObserver(gains, dt)
    x1, x2 = 0.1, 0.0
    errors = []
    for k in range(30000):
        t = k * dt
        u = math.sin(3.0 * t)
        d = -40.0 + 10.0 * math.sin(2.0 * t)
        eso.update(x1, u)
        x2_new = x2 + dt * (gains.theta1n * u + gains.theta2n * x2 + d)
        x1 += dt * x2
        x2 = x2_new
        d_next = -40.0 + 10.0 * math.sin(2.0 * (t + dt))
        errors.append((eso.x1_hat - x1, eso.x2_hat - x2, eso.x3_hat - d_next))
    err = np.abs(np.array(errors))
    assert err[:100, 2].max() > 10.0  # it starts far off (x_hat(0) = 0, d = -40) ...
    assert err[-5000:, 0].max() < 1e-5  # ... and converges: d' = 20 cos gives a small lag only
    assert err[-5000:, 1].max() < 5e-3
    assert err[-5000:, 2].max() < 0.5


@pytest.mark.parametrize('steps', [0, 1, 4])
def test_late_current_correction_equals_stepping_with_the_right_current(steps):
    """A step taken with a substituted current, repaired `steps` steps later.

    Equals the exact run.
    """
    gains, dt = EsoGains(), 1e-3
    rng = np.random.default_rng(7)
    ys, us = rng.normal(0.0, 0.1, 8), rng.normal(0.0, 5.0, 8)
    exact, wrong = (0.01, -0.2, 3.0), (0.01, -0.2, 3.0)
    for k in range(1 + steps):
        exact = eso_step(*exact, ys[k], us[k], dt, gains)
        wrong = eso_step(
            *wrong, ys[k], (us[k] - 2.5) if k == 0 else us[k], dt, gains
        )  # sample 0 substituted
    assert not np.allclose(wrong, exact, rtol=0.0, atol=1e-9)
    repaired = np.add(wrong, input_current_correction(2.5, steps, dt, gains))
    assert np.allclose(repaired, exact, rtol=1e-12, atol=1e-12)


def test_ppf_transform_inverse_and_r_against_numerical_derivative():
    ppf = PrescribedPerformance()
    t = np.linspace(0.0, 8.0, 801)
    rho, rho_d, _ = ppf.rho_derivatives(t)
    e = 0.8 * rho * np.sin(3.0 * t)  # inside the envelope
    e_dot = 0.8 * (rho_d * np.sin(3.0 * t) + rho * 3.0 * np.cos(3.0 * t))
    tr = transform_error(e, rho, ppf)
    assert np.all(tr.inside)
    assert np.allclose(inverse_transform(tr.z, rho, ppf), e, atol=1e-12)
    z_dot_numeric = np.gradient(tr.z, t)
    z_dot_12 = tr.r * (e_dot - rho_d * e / rho)  # eq. (12) with the corrected r
    assert np.allclose(z_dot_12[5:-5], z_dot_numeric[5:-5], rtol=2e-3, atol=1e-3)
    assert ppf.rho(0.0) == pytest.approx(0.25) and ppf.rho(100.0) == pytest.approx(0.05)


def test_ppf_clamps_outside_the_bounds_and_reports_it():
    ppf = PrescribedPerformance()
    tr = transform_error(np.array([-1.0, 0.0, 0.3]), 0.25, ppf)
    assert list(tr.inside) == [False, True, False]
    assert np.all(np.isfinite(tr.z)) and np.all(np.isfinite(tr.r))
    assert tr.z[0] < -4.0 and tr.z[2] > 4.0 and tr.z[1] == 0.0
    with pytest.raises(ValueError, match='rho_inf_rad'):
        PrescribedPerformance(rho0_rad=0.01, rho_inf_rad=0.05)


@pytest.mark.slow
def test_holding_brake_stops_the_joint_and_holds_it_against_the_external_torque():
    from actuator_plant.model import JointPlant, PlantParameters

    plant = JointPlant(PlantParameters(), 1.0e-3)
    for _ in range(200):
        plant.step(10.0)  # moving at several rad/s
    assert abs(plant.velocity_rad_s) > 1.0
    moved, v = plant.position_rad, plant.velocity_rad_s
    for _ in range(500):
        plant.step(0.0, brake=True)
    held = plant.position_rad
    assert plant.velocity_rad_s == 0.0
    assert (held - moved) * v >= 0.0 and abs(held - moved) < 0.5 * abs(v)  # stopped ahead
    for _ in range(3000):  # 3 s of eq. (40)'s torque: the brake holds
        plant.step(0.0, brake=True)
    assert plant.position_rad == held and plant.velocity_rad_s == 0.0
    free = JointPlant(PlantParameters(), 1.0e-3, position_rad=held)
    for _ in range(500):
        free.step(0.0)
    assert abs(free.position_rad - held) > 0.5  # without it the external torque drives the joint
    weak = JointPlant(dataclasses.replace(PlantParameters(), brake_holding_torque_nm=5.0), 1.0e-3)
    for _ in range(500):
        weak.step(0.0, brake=True)  # 5 N m cannot hold 20-30 N m: it slips
    assert abs(weak.position_rad) > 0.01


def test_the_truth_carries_the_torques_its_disturbance_parts_come_from():
    """Each part of d is its torque of eq. (6), (40), (42) over J (and the gear), per sample."""
    from actuator_plant.model import JointPlant, PlantParameters

    plant = JointPlant(PlantParameters(), 1.0e-3)
    for _ in range(50):
        plant.step(5.0)
    parts = plant.truth(5.0)
    f, gear = parts.forces, PlantParameters().nominal.gear_ratio
    assert parts.stirring_rad_s2 == -f.stirring_torque_nm / (f.inertia_kg_m2 * gear)
    assert parts.external_rad_s2 == -f.external_torque_nm / (f.inertia_kg_m2 * gear**2)
    assert parts.seal_rad_s2 == -f.seal_torque_nm / (f.inertia_kg_m2 * gear**2)
    assert f.stirring_torque_nm != 0.0 and f.external_torque_nm != 0.0


def test_derived_constants_are_python_floats_for_one_condition_and_arrays_for_a_batch():
    """One condition: floats (the scalar path's speed); a batch of two: an array per constant.

    The stirring coefficient is k mu of eq. (6)-(7) with the viscosity it reports.
    """
    from actuator_plant.model import PlantParameters, WorkingCondition, derive_constants
    from actuator_plant.oil import dynamic_viscosity_pa_s, stirring_geometry_constant_m3

    params = PlantParameters()
    one = derive_constants(params)
    fields = ('stirring_coefficient_nm_s_rad', 'viscosity_pa_s', 'seal_offset_nm')
    assert all(type(getattr(one, f)) is float for f in fields)
    mu = dynamic_viscosity_pa_s(2.0, 10.0e6, params.oil)
    assert one.viscosity_pa_s == mu
    assert one.stirring_coefficient_nm_s_rad == stirring_geometry_constant_m3(params.geometry) * mu
    both = WorkingCondition(
        pressure_pa=np.array([0.0, 10.0e6]), temperature_c=np.array([25.0, 2.0])
    )
    batch = derive_constants(dataclasses.replace(params, condition=both))
    assert all(np.shape(getattr(batch, f)) == (2,) for f in fields)
    assert batch.viscosity_pa_s[1] == mu


def test_depth_range_is_the_surface_to_11000_m_both_included():
    """0 m and 11000 m are depths; a nanometre above or below is refused, with the range."""
    assert WorkingCondition.at_depth(0.0).pressure_pa == 0.0
    deepest = WorkingCondition.at_depth(11000.0, temperature_c=1.0)
    assert deepest == WorkingCondition(SEAWATER_DENSITY_KG_M3 * GRAVITY_M_S2 * 11000.0, 1.0)
    assert WorkingCondition.at_depth(500.0).temperature_c == 2.0  # the deep sea's by default
    for depth in (11000.0 + 1e-9, -1e-9):
        with pytest.raises(ValueError) as refused:
            WorkingCondition.at_depth(depth)
        assert str(refused.value) == (
            f'depth_m = {depth} is outside its valid range [0, 11000] m: water depth'
        )


def test_working_condition_by_name():
    """The named ones, 'depth' (with the given temperature), 'custom' (the given one)."""
    given = WorkingCondition(pressure_pa=3.0e6, temperature_c=9.0)
    assert working_condition('lab', 50.0, given) == WorkingCondition(0.0, 25.0)
    assert working_condition('deep_sea', 50.0, given) == WorkingCondition(10.0e6, 2.0)
    assert working_condition('depth', 50.0, given) == WorkingCondition.at_depth(50.0, 9.0)
    assert working_condition('depth') == WorkingCondition.at_depth(1000.0, 2.0)
    assert working_condition('custom', 50.0, given) is given
    assert working_condition('custom') == WorkingCondition()
    with pytest.raises(ValueError) as refused:
        working_condition('mars')
    assert str(refused.value) == (
        "working_condition must be one of lab, deep_sea, depth, custom: 'mars'"
    )
    assert CONDITION_CHOICES == ('lab', 'deep_sea', 'depth', 'custom')


def test_sample_time_range_is_1_us_to_1_s_both_included():
    """dt_s of 1 us and of 1 s build a plant; just outside either is refused, with the range."""
    assert JointPlant(PlantParameters(), 1e-6).period_ns == 1_000
    assert JointPlant(PlantParameters(), 1.0).period_ns == 1_000_000_000
    for dt in (np.nextafter(1e-6, 0.0), np.nextafter(1.0, 2.0)):
        with pytest.raises(ValueError) as refused:
            JointPlant(PlantParameters(), dt)
        assert str(refused.value) == (
            f'dt_s = {dt} is outside its valid range [1e-06, 1] s: sample time'
        )


#: Drift and external torque on, no seal friction or stirring: a braked joint by hand.
BRAKED = dataclasses.replace(
    PlantParameters(substeps=2), with_seal_friction=False, with_stirring=False
)


def _braked_by_hand(t, q, v, u, dt):
    """Semi-implicit Euler of the brake with (1), (40), (41) written out.

    The brake: docs/safety.md#command-gate-and-holding-brake.

    Moving: the brake's T_h opposes the motion; a sub-interval whose velocity would change
    sign ends at rest. At rest: held while the other torques stay within T_h, else T_h
    opposes their excess.
    """
    p = BRAKED
    n, d, e = p.nominal, p.drift, p.external
    gear = n.gear_ratio
    h = dt / p.substeps
    for i in range(p.substeps):
        ts = t + i * h
        inertia = n.inertia_kg_m2 * (
            1 + d.inertia_amplitude * math.sin(d.inertia_frequency_rad_s * ts)
        )
        kt = n.torque_constant_nm_a * (
            1 + d.torque_constant_amplitude * math.cos(d.torque_constant_frequency_rad_s * ts)
        )
        kb = n.viscous_coefficient_nm_s_rad * (
            1 + d.viscous_amplitude * math.cos(d.viscous_frequency_rad_s * ts)
        )
        external = e.mean_nm * (1 + e.relative_amplitude * math.sin(e.frequency_rad_s * ts))
        free = (kt * u - kb * gear * v - external / gear) / (inertia * gear)
        hold = p.brake_holding_torque_nm / (inertia * gear * gear)
        if v != 0.0:
            new = v + h * (free - math.copysign(hold, v))
            new = 0.0 if new * v < 0.0 else new
        elif abs(free) <= hold:
            new = 0.0
        else:
            new = h * (free - math.copysign(hold, free))
        q, v = q + 0.5 * h * (v + new), new
    return q, v


@pytest.mark.parametrize(
    'v, u',
    [
        (2.0, 0.0),  # moving: slowed by T_h, still moving
        (-2.0, 3.0),  # the other way, against a current
        (0.05, 0.0),  # stops within the first sub-interval
        (0.0, 0.0),  # at rest: held against eq. (40)'s 20-30 N m
        (0.0, 20.0),  # at rest, driven beyond T_h: slips
        (0.0, -20.0),
    ],
)
def test_braked_step_by_hand(v, u):
    """One sample of the brake at t = 0.3 s (drift and external torque on), 2 sub-intervals."""
    c = derive_constants(BRAKED)
    q, q_dot = braked_step(0.3, 0.1, v, u, 1e-3, c)
    want = _braked_by_hand(0.3, 0.1, v, u, 1e-3)
    assert (q, q_dot) == pytest.approx(want, rel=1e-12, abs=1e-15)
    if u == 0.0 and v == 0.0:
        assert (q, q_dot) == (0.1, 0.0)  # held exactly


def test_the_brake_holds_a_joint_with_no_torque_on_it():
    """The loss-free joint at rest at 0 A (no torque at all): held, velocity exactly 0."""
    c = derive_constants(PlantParameters().ideal())
    assert braked_step(0.3, 0.1, 0.0, 0.0, 1e-3, c) == (0.1, 0.0)
    q, v = braked_step(0.3, np.array([0.1, 0.2]), np.zeros(2), np.zeros(2), 1e-3, c)
    assert list(q) == [0.1, 0.2] and list(v) == [0.0, 0.0]


def test_braked_step_and_a_partly_braked_batch_go_element_by_element():
    """Arrays: each element as its own scalar run; a batch braked in part brakes only those."""
    c = derive_constants(BRAKED)
    v = np.array([2.0, -2.0, 0.05, 0.0, 0.0])
    u = np.array([0.0, 3.0, 0.0, 0.0, 20.0])
    q, q_dot = braked_step(0.3, np.full(5, 0.1), v, u, 1e-3, c)
    for i in range(5):
        assert (q[i], q_dot[i]) == braked_step(0.3, 0.1, v[i], u[i], 1e-3, c)
    batch = JointPlant(BRAKED, 1e-3, position_rad=np.zeros(2))
    single = [JointPlant(BRAKED, 1e-3) for _ in range(2)]
    for k in range(30):
        brake = np.array([k >= 10, False])
        batch.step(np.array([8.0, 8.0]), brake)
        for i in range(2):
            single[i].step(8.0, bool(brake[i]))
    assert list(batch.position_rad) == [s.position_rad for s in single]
    assert list(batch.velocity_rad_s) == [s.velocity_rad_s for s in single]
    assert single[0].velocity_rad_s != single[1].velocity_rad_s
