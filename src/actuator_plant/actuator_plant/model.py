# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Deep-sea oil-filled joint actuator, paper eq. (1)-(5) with the losses (6)-(7), (40)-(42).

The motion equation (1), J (N q'') = k_t u - k_b (N q') - T_v - T_d/N - T_f/N, is
integrated with the motor current u held over each sample (zero-order hold, as a current
amplifier does), by classical Runge-Kutta on ``substeps`` equal sub-intervals.

Every function works on floats and, elementwise, on numpy arrays of the same shape, so
one implementation serves a single run and a vectorised sweep over many scenarios.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from actuator_core import limits
from actuator_core import xmath as xm
from actuator_core.params import build, check_value, spec, validate
from actuator_core.timing import period_ns, sample_time_s
from actuator_core.xmath import FloatOrArray
from actuator_plant.oil import (
    PA_PER_MPA,
    MotorGeometry,
    OilProperties,
    dynamic_viscosity_pa_s,
    stirring_geometry_constant_m3,
)

#: Sea-water density [kg/m^3] and gravity [m/s^2] for the hydrostatic pressure at a depth.
SEAWATER_DENSITY_KG_M3 = 1025.0
GRAVITY_M_S2 = 9.80665


@dataclass(frozen=True)
class JointNominal:
    """Nominal joint parameters of Table 1 and the model coefficients of eq. (3)."""

    inertia_kg_m2: float = spec(
        limits.NOMINAL_INERTIA_KG_M2,
        'J_n: nominal inertia at the motor shaft (Table 1)',
        'kg m^2',
        0.0,
        10.0,
        low_open=True,
    )
    torque_constant_nm_a: float = spec(
        limits.NOMINAL_TORQUE_CONSTANT_NM_A,
        'k_tn: nominal motor torque constant (Table 1)',
        'N m/A',
        0.0,
        100.0,
        low_open=True,
    )
    viscous_coefficient_nm_s_rad: float = spec(
        limits.NOMINAL_VISCOUS_NM_S_RAD,
        'k_bn: nominal motor viscous coefficient (Table 1)',
        'N m s/rad',
        0.0,
        10.0,
    )
    gear_ratio: float = spec(
        limits.NOMINAL_GEAR_RATIO,
        'N: gear reduction ratio (Table 1)',
        '',
        0.0,
        1.0e4,
        low_open=True,
    )

    def __post_init__(self) -> None:
        """Refuse non-physical values."""
        validate(self)

    @property
    def theta1n(self) -> float:
        """theta_1n = k_tn / (J_n N) [rad/s^2/A], eq. (3)."""
        return self.torque_constant_nm_a / (self.inertia_kg_m2 * self.gear_ratio)

    @property
    def theta2n(self) -> float:
        """theta_2n = -k_bn / J_n [1/s], eq. (3)."""
        return -self.viscous_coefficient_nm_s_rad / self.inertia_kg_m2


@dataclass(frozen=True)
class ParameterDrift:
    """Core-loss parameter drift of eq. (41): relative amplitudes and angular frequencies."""

    inertia_amplitude: float = spec(
        0.2, 'relative amplitude of J = J_n (1 + a sin(w t))', '', 0.0, 0.99
    )
    inertia_frequency_rad_s: float = spec(
        0.5 * math.pi, 'angular frequency w of the inertia drift', 'rad/s', 0.0, 1.0e3
    )
    torque_constant_amplitude: float = spec(
        0.3, 'relative amplitude of k_t = k_tn (1 + a cos(w t))', '', 0.0, 0.99
    )
    torque_constant_frequency_rad_s: float = spec(
        0.3 * math.pi, 'angular frequency of the k_t drift', 'rad/s', 0.0, 1.0e3
    )
    viscous_amplitude: float = spec(
        0.2, 'relative amplitude of k_b = k_bn (1 + a cos(w t))', '', 0.0, 0.99
    )
    viscous_frequency_rad_s: float = spec(
        0.3 * math.pi, 'angular frequency of the k_b drift', 'rad/s', 0.0, 1.0e3
    )

    def __post_init__(self) -> None:
        """Amplitudes below 1 keep J and k_t positive."""
        validate(self)


@dataclass(frozen=True)
class ExternalTorque:
    """External torque at the output shaft, eq. (40): T_d = mean (1 + a sin(w t)) [N m]."""

    mean_nm: float = spec(20.0, 'mean external torque at the output shaft', 'N m', -1.0e4, 1.0e4)
    relative_amplitude: float = spec(0.5, 'relative amplitude a of the sinusoid', '', -10.0, 10.0)
    frequency_rad_s: float = spec(
        0.5 * math.pi, 'angular frequency w of the sinusoid', 'rad/s', 0.0, 1.0e3
    )

    def __post_init__(self) -> None:
        """Refuse out-of-range values."""
        validate(self)


@dataclass(frozen=True)
class SealFriction:
    """Dynamic seal friction at the output shaft, eq. (42) [N m].

    (c0 + e^(cv|q'|) + e^(cp P)) sign(q').
    """

    base_nm: float = spec(
        1.0, 'c0: constant part of the seal friction amplitude', 'N m', 0.0, 1.0e3
    )
    velocity_coefficient_s_rad: float = spec(
        0.3591, 'cv: velocity exponent coefficient', 's/rad', 0.0, 10.0
    )
    pressure_coefficient_per_mpa: float = spec(
        0.1504, 'cp: pressure exponent coefficient', '1/MPa', 0.0, 1.0
    )

    def __post_init__(self) -> None:
        """Refuse out-of-range values."""
        validate(self)


@dataclass(frozen=True)
class WorkingCondition:
    """Oil pressure (gauge) [Pa] and temperature [degC] of a working condition."""

    pressure_pa: float = spec(
        10.0e6, 'oil pressure (gauge; the housing is pressure-compensated)', 'Pa', 0.0, 120.0e6
    )
    temperature_c: float = spec(2.0, 'oil temperature', 'degC', -10.0, 80.0)

    def __post_init__(self) -> None:
        """Pressure from the surface to below the deepest trench; liquid oil temperatures."""
        validate(self)

    @classmethod
    def lab(cls) -> 'WorkingCondition':
        """Return the normal laboratory condition of the paper: 0 MPa, 25 degC."""
        return cls(pressure_pa=0.0, temperature_c=25.0)

    @classmethod
    def deep_sea(cls) -> 'WorkingCondition':
        """Deep-sea condition of the paper (1000 m): 10 MPa, 2 degC."""
        return cls(pressure_pa=10.0e6, temperature_c=2.0)

    @classmethod
    def at_depth(cls, depth_m: float, temperature_c: float = 2.0) -> 'WorkingCondition':
        """Hydrostatic pressure rho g depth of sea water at ``depth_m``.

        The oil is pressure-compensated.
        """
        check_value(
            'depth_m',
            depth_m,
            {
                'low': 0.0,
                'high': 11000.0,
                'low_open': False,
                'unit': 'm',
                'description': 'water depth',
            },
        )
        return cls(
            pressure_pa=SEAWATER_DENSITY_KG_M3 * GRAVITY_M_S2 * depth_m,
            temperature_c=temperature_c,
        )


#: The paper's named working conditions, the one table every node and tool reads.
CONDITIONS = {'lab': WorkingCondition.lab, 'deep_sea': WorkingCondition.deep_sea}
#: What a joint's ``working_condition`` parameter takes: a named one, or 'depth' (the
#: hydrostatic pressure of ``depth_m``) or 'custom' (pressure and temperature as given).
CONDITION_CHOICES = (*CONDITIONS, 'depth', 'custom')
#: The simulated joint's node name, which its section of a parameter file carries.
PLANT_NODE_NAME = 'actuator_plant'
#: A joint's working condition and depth when its parameters name none (the plant node's).
DEFAULT_CONDITION, DEFAULT_DEPTH_M = 'deep_sea', 1000.0


def working_condition(
    name: str, depth_m: float = DEFAULT_DEPTH_M, given: 'WorkingCondition | None' = None
) -> WorkingCondition:
    """Return the working condition ``name`` (one of CONDITION_CHOICES).

    'depth' takes ``depth_m`` and the temperature of ``given``; 'custom' returns ``given``.
    """
    given = given if given is not None else WorkingCondition()
    if name in CONDITIONS:
        return CONDITIONS[name]()
    if name == 'depth':
        return WorkingCondition.at_depth(depth_m, given.temperature_c)
    if name == 'custom':
        return given
    raise ValueError(f'working_condition must be one of {", ".join(CONDITION_CHOICES)}: {name!r}')


@dataclass(frozen=True)
class PlantParameters:
    """Everything the simulated joint needs; each effect can be switched off for tests."""

    nominal: JointNominal = field(default_factory=JointNominal)
    drift: ParameterDrift = field(default_factory=ParameterDrift)
    external: ExternalTorque = field(default_factory=ExternalTorque)
    seal: SealFriction = field(default_factory=SealFriction)
    oil: OilProperties = field(default_factory=OilProperties)
    geometry: MotorGeometry = field(default_factory=MotorGeometry)
    condition: WorkingCondition = field(default_factory=WorkingCondition)
    with_drift: bool = spec(True, 'apply the parameter drift of eq. (41)')
    with_external_torque: bool = spec(True, 'apply the external torque of eq. (40)')
    with_seal_friction: bool = spec(True, 'apply the seal friction of eq. (42)')
    with_stirring: bool = spec(True, 'apply the oil stirring loss of eq. (6)-(7)')
    substeps: int = spec(4, 'Runge-Kutta sub-intervals per sample', '', 1, 100)
    brake_holding_torque_nm: float = spec(
        50.0,
        'holding brake at the output shaft: the largest torque it holds '
        'the joint against (above the 30 N m peak of eq. (40))',
        'N m',
        0.0,
        1.0e4,
    )

    def __post_init__(self) -> None:
        """Refuse a substep count outside 1..100."""
        validate(self)

    def ideal(self) -> 'PlantParameters':
        """Return the same joint with nominal parameters and no loss or disturbance.

        Exactly model (5) with d = 0.
        """
        return replace(
            self,
            with_drift=False,
            with_external_torque=False,
            with_seal_friction=False,
            with_stirring=False,
        )


def plant_from_values(values: dict) -> PlantParameters:
    """Return the joint a plant node runs with ``values``, its parameters by dotted names."""
    params = build(PlantParameters, values)
    condition = working_condition(
        values.get('working_condition', DEFAULT_CONDITION),
        values.get('depth_m', DEFAULT_DEPTH_M),
        params.condition,
    )
    return replace(params, condition=condition)


class PlantConstants(NamedTuple):
    """Per-condition constants derived once from ``PlantParameters``.

    viscosity, seal pressure term.
    """

    params: PlantParameters
    stirring_coefficient_nm_s_rad: float  # k * mu, multiplies the rotor speed
    viscosity_pa_s: float
    seal_offset_nm: float  # c0 + exp(cp P)
    # The parameters the per-instant terms read, flat (the same values, fewer look-ups):
    gear_ratio: float
    nominal: tuple  # (J_n, k_tn, k_bn)
    drift: tuple | None  # (J_n, a_J, w_J, k_tn, a_k, w_k, k_bn, a_b, w_b); None without drift
    external: tuple | None  # (mean, relative amplitude, w) of eq. (40); None without it
    seal_velocity_coefficient: object  # c_v of eq. (42); None without seal friction


def derive_constants(params: PlantParameters) -> PlantConstants:
    """Evaluate the oil viscosity (7) and the geometry constant (6) for the working condition."""
    condition = params.condition
    mu = dynamic_viscosity_pa_s(condition.temperature_c, condition.pressure_pa, params.oil)
    k_mu = stirring_geometry_constant_m3(params.geometry) * mu if params.with_stirring else 0.0
    seal_offset = params.seal.base_nm + np.exp(
        params.seal.pressure_coefficient_per_mpa * condition.pressure_pa / PA_PER_MPA
    )
    n, d, e = params.nominal, params.drift, params.external
    nominal = (n.inertia_kg_m2, n.torque_constant_nm_a, n.viscous_coefficient_nm_s_rad)
    return PlantConstants(
        params,
        _plain(k_mu),
        _plain(mu),
        _plain(seal_offset),
        n.gear_ratio,
        nominal,
        (
            n.inertia_kg_m2,
            d.inertia_amplitude,
            d.inertia_frequency_rad_s,
            n.torque_constant_nm_a,
            d.torque_constant_amplitude,
            d.torque_constant_frequency_rad_s,
            n.viscous_coefficient_nm_s_rad,
            d.viscous_amplitude,
            d.viscous_frequency_rad_s,
        )
        if params.with_drift
        else None,
        (e.mean_nm, e.relative_amplitude, e.frequency_rad_s)
        if params.with_external_torque
        else None,
        params.seal.velocity_coefficient_s_rad if params.with_seal_friction else None,
    )


def _plain(x):
    """Return a 0-d numpy value as a Python float (scalar arithmetic is several times faster).

    Arrays unchanged.
    """
    return float(x) if np.ndim(x) == 0 else x


class JointForces(NamedTuple):
    """Physical parameters (41) and torques (6), (40), (42) at one instant."""

    inertia_kg_m2: FloatOrArray
    torque_constant_nm_a: FloatOrArray
    viscous_coefficient_nm_s_rad: FloatOrArray
    stirring_torque_nm: FloatOrArray  # T_v at the motor shaft
    external_torque_nm: FloatOrArray  # T_d at the output shaft
    seal_torque_nm: FloatOrArray  # T_f at the output shaft


class TimeTerms(NamedTuple):
    """What eq. (40)-(41) give at one instant, whatever the velocity."""

    inertia_kg_m2: FloatOrArray
    torque_constant_nm_a: FloatOrArray
    viscous_coefficient_nm_s_rad: FloatOrArray
    external_torque_nm: FloatOrArray  # T_d at the output shaft


def time_terms(t: float, c: PlantConstants) -> TimeTerms:
    """Drifting parameters (41) and external torque (40) at time ``t`` [s]."""
    if c.drift is not None:
        j_n, a_j, w_j, k_n, a_k, w_k, b_n, a_b, w_b = c.drift
        inertia = j_n * (1.0 + a_j * xm.sin(w_j * t))
        torque_constant = k_n * (1.0 + a_k * xm.cos(w_k * t))
        viscous = b_n * (1.0 + a_b * xm.cos(w_b * t))
    else:
        inertia, torque_constant, viscous = c.nominal
    if c.external is not None:
        mean, amplitude, w = c.external
        external = mean * (1.0 + amplitude * xm.sin(w * t))
    else:
        external = 0.0 * t
    return TimeTerms(inertia, torque_constant, viscous, external)


def velocity_terms(velocity_rad_s, c: PlantConstants):
    """Stirring loss T_v (6) at the motor shaft and seal friction T_f (42) [N m]."""
    stirring = c.stirring_coefficient_nm_s_rad * c.gear_ratio * velocity_rad_s
    if c.seal_velocity_coefficient is not None:
        # sign(0) = 0: at rest the seal friction is zero in this model (no stiction state).
        seal = (
            c.seal_offset_nm + xm.exp(c.seal_velocity_coefficient * xm.fabs(velocity_rad_s))
        ) * xm.sign(velocity_rad_s)
    else:
        seal = 0.0 * velocity_rad_s
    return stirring, seal


def joint_forces(t: float, velocity_rad_s, c: PlantConstants) -> JointForces:
    """Parameters and loss torques, eq. (6), (40)-(42).

    At time ``t`` [s] and joint velocity q' [rad/s].
    """
    inertia, torque_constant, viscous, external = time_terms(t, c)
    stirring, seal = velocity_terms(velocity_rad_s, c)
    return JointForces(inertia, torque_constant, viscous, stirring, external, seal)


def acceleration_at(terms: TimeTerms, velocity_rad_s, current_a, c: PlantConstants):
    """Compute q'' from eq. (1) with the instant's ``terms``: see ``joint_acceleration``."""
    stirring, seal = velocity_terms(velocity_rad_s, c)
    gear = c.gear_ratio
    motor_torque = (
        terms.torque_constant_nm_a * current_a
        - terms.viscous_coefficient_nm_s_rad * gear * velocity_rad_s
    )
    load = stirring + (terms.external_torque_nm + seal) / gear
    return (motor_torque - load) / (terms.inertia_kg_m2 * gear)


def joint_acceleration(t: float, velocity_rad_s, current_a, c: PlantConstants):
    """Compute q'' from eq. (1): (k_t u - k_b N q' - T_v - T_d/N - T_f/N) / (J N) [rad/s^2]."""
    return acceleration_at(time_terms(t, c), velocity_rad_s, current_a, c)


class DisturbanceParts(NamedTuple):
    """The lumped disturbance d of eq. (5) split into its sources [rad/s^2], with the torques."""

    acceleration_rad_s2: FloatOrArray
    disturbance_rad_s2: FloatOrArray
    parametric_rad_s2: FloatOrArray
    stirring_rad_s2: FloatOrArray
    external_rad_s2: FloatOrArray
    seal_rad_s2: FloatOrArray
    forces: JointForces


def disturbance_parts(t: float, velocity_rad_s, current_a, c: PlantConstants) -> DisturbanceParts:
    """Return the true lumped disturbance and its parts, eq. (4)-(5).

    d = q'' - theta1n u - theta2n q'.
    """
    f = joint_forces(t, velocity_rad_s, c)
    n = c.params.nominal
    gear = n.gear_ratio
    theta1 = f.torque_constant_nm_a / (f.inertia_kg_m2 * gear)
    theta2 = -f.viscous_coefficient_nm_s_rad / f.inertia_kg_m2
    parametric = (theta1 - n.theta1n) * current_a + (theta2 - n.theta2n) * velocity_rad_s
    stirring = -f.stirring_torque_nm / (f.inertia_kg_m2 * gear)
    external = -f.external_torque_nm / (f.inertia_kg_m2 * gear**2)
    seal = -f.seal_torque_nm / (f.inertia_kg_m2 * gear**2)
    d = parametric + stirring + external + seal
    acceleration = n.theta1n * current_a + n.theta2n * velocity_rad_s + d
    return DisturbanceParts(acceleration, d, parametric, stirring, external, seal, f)


def rk4_step(t: float, position_rad, velocity_rad_s, current_a, dt: float, c: PlantConstants):
    """Advance (q, q') by ``dt`` [s] with the current held, RK4 on ``substeps`` sub-intervals."""
    n_sub = c.params.substeps
    h = dt / n_sub
    x1, x2 = position_rad, velocity_rad_s
    for i in range(n_sub):
        ts = t + i * h
        middle = time_terms(ts + 0.5 * h, c)  # stages 2 and 3 share their instant
        a1 = acceleration_at(time_terms(ts, c), x2, current_a, c)
        v2 = x2 + 0.5 * h * a1
        a2 = acceleration_at(middle, v2, current_a, c)
        v3 = x2 + 0.5 * h * a2
        a3 = acceleration_at(middle, v3, current_a, c)
        v4 = x2 + h * a3
        a4 = acceleration_at(time_terms(ts + h, c), v4, current_a, c)
        x1 = x1 + h / 6.0 * (x2 + 2.0 * v2 + 2.0 * v3 + v4)
        x2 = x2 + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return x1, x2


def braked_step(t: float, position_rad, velocity_rad_s, current_a, dt: float, c: PlantConstants):
    """Advance (q, q') by ``dt`` with the holding brake engaged.

    Beyond the paper; docs/safety.md#command-gate-and-holding-brake. The brake is a friction torque
    of up to T_h at the output shaft: it opposes motion with T_h until the joint stops, and holds
    it at rest while the other torques stay below T_h. Semi-implicit Euler on ``substeps``
    sub-intervals; a sub-interval in which the velocity would change sign ends at rest. Elementwise
    on arrays.
    """
    n_sub = c.params.substeps
    h = dt / n_sub
    gear = c.params.nominal.gear_ratio
    x1, x2 = position_rad, velocity_rad_s
    for i in range(n_sub):
        ts = t + i * h
        a_free = joint_acceleration(ts, x2, current_a, c)
        a_hold = c.params.brake_holding_torque_nm / (
            joint_forces(ts, x2, c).inertia_kg_m2 * gear * gear
        )
        moving = x2 != 0.0
        a_rest = xm.where(
            xm.fabs(a_free) <= a_hold, 0.0 * a_free, a_free - xm.sign(a_free) * a_hold
        )
        a = xm.where(moving, a_free - xm.sign(x2) * a_hold, a_rest)
        v = x2 + h * a
        v = xm.where(moving & (xm.sign(v) != xm.sign(x2)), 0.0 * v, v)
        x1 = x1 + 0.5 * h * (x2 + v)
        x2 = v
    return x1, x2


class JointPlant:
    """The simulated joint as a sampled system: state (q, q') at sample k, t_k = k * dt."""

    def __init__(self, params: PlantParameters, dt_s: float, position_rad=0.0, velocity_rad_s=0.0):
        """Start at sample 0 at rest at q = ``position_rad``.

        Arrays give one joint per element.
        """
        check_value(
            'dt_s',
            dt_s,
            {
                'low': 1.0e-6,
                'high': 1.0,
                'low_open': False,
                'unit': 's',
                'description': 'sample time',
            },
        )
        self.constants = derive_constants(params)
        self.period_ns = period_ns(dt_s)
        self.dt_s = dt_s
        self.sample_index = 0
        self.position_rad = position_rad
        self.velocity_rad_s = velocity_rad_s

    @property
    def params(self) -> PlantParameters:
        """The parameters this plant was built with."""
        return self.constants.params

    @property
    def time_s(self) -> float:
        """t_k of the current sample [s]."""
        return sample_time_s(self.sample_index * self.period_ns)

    def step(self, current_a, brake=False) -> None:
        """Integrate eq. (1) over [t_k, t_k+1]; k -> k + 1.

        With ``current_a`` held (and the brake where engaged).
        """
        free = rk4_step(
            self.time_s,
            self.position_rad,
            self.velocity_rad_s,
            current_a,
            self.dt_s,
            self.constants,
        )
        if xm.any_true(brake):
            held = braked_step(
                self.time_s,
                self.position_rad,
                self.velocity_rad_s,
                current_a,
                self.dt_s,
                self.constants,
            )
            free = (xm.where(brake, held[0], free[0]), xm.where(brake, held[1], free[1]))
        self.position_rad, self.velocity_rad_s = free
        self.sample_index += 1

    def truth(self, current_a) -> DisturbanceParts:
        """Return the true acceleration and lumped disturbance at t_k.

        With ``current_a`` the current being applied.
        """
        return disturbance_parts(self.time_s, self.velocity_rad_s, current_a, self.constants)
