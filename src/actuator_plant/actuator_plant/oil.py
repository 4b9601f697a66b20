# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Oil stirring loss of the oil-filled motor, paper eq. (6)-(7), and the oil's viscosity.

The paper's Table 2 lost its viscosity values mu_0. They are derived here for the paper's
oil (ISO VG 22 hydraulic oil) at any temperature, from figures with a public source:

* ISO 3448: grade VG 22 has a kinematic viscosity of 22 mm^2/s (+-10 %) at 40 degC.
* A mineral VG 22 hydraulic oil of viscosity index about 100 has about 4.3 mm^2/s at
  100 degC (ASTM D2270 tables: VI 100 at nu40 = 22 gives nu100 = 4.3 to 4.4 mm^2/s;
  product data sheets of HM/HLP 22 oils list 4.2-4.4 mm^2/s).
* ASTM D341 (Walther): log10(log10(nu + 0.7)) = A - B*log10(T), nu in mm^2/s, T in K,
  through the two points above, gives nu at any temperature.
* Density about 870 kg/m^3 at 15 degC (HM 22 data sheets list 0.86-0.88 g/ml) with the
  mineral-oil expansion coefficient of about 6.5e-4 1/K (ASTM D1250 order of magnitude).

Result: mu_0 = 142 mPa s at 2 degC and 36.5 mPa s at 25 degC (see ``dynamic_viscosity``).

Table 2's pressure-viscosity coefficient alpha = 1/(a + b*P) is used as printed, with
alpha in 1/Pa and the pressure of eq. (7) in Pa; only the small correction b*P takes P in
MPa, as its footnote says (with P in MPa in exp(alpha*P) as well, the pressure would have
no effect at all). Between and beyond the two printed temperatures a and b are
interpolated linearly in temperature. Note: as printed, alpha is larger at 25 degC than
at 2 degC, the opposite of most mineral oils; the paper's laboratory case has P = 0,
where alpha has no effect, so only the 2 degC value matters for its results.

Table 3 prints d1 = 63 mm (rotor end face) and d2 = 37.5 mm (housing end face), which
makes the disk term of eq. (6) negative: the annulus of the disk loss runs from the
smaller to the larger diameter, so d1 = 37.5 mm and d2 = 63 mm here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from actuator_core.params import spec, validate

PA_PER_MPA = 1.0e6
KELVIN_OFFSET = 273.15


@dataclass(frozen=True)
class OilProperties:
    """Viscosity data of the filling oil (defaults: ISO VG 22 mineral hydraulic oil)."""

    nu40_mm2_s: float = spec(
        22.0,
        'kinematic viscosity at 40 degC (ISO 3448 grade)',
        'mm^2/s',
        0.0,
        1.0e4,
        low_open=True,
    )
    nu100_mm2_s: float = spec(
        4.3, 'kinematic viscosity at 100 degC', 'mm^2/s', 0.0, 1.0e4, low_open=True
    )
    density15_kg_m3: float = spec(870.0, 'oil density at 15 degC', 'kg/m^3', 500.0, 2000.0)
    expansion_per_k: float = spec(
        6.5e-4, 'volumetric thermal expansion coefficient', '1/K', 0.0, 1.0e-2
    )
    alpha_a_2c_pa: float = spec(
        4.49e7,
        'Table 2: alpha = 1/(a + b P[MPa]) at 2 degC, term a',
        'Pa',
        0.0,
        1.0e12,
        low_open=True,
    )
    alpha_b_2c_pa_per_mpa: float = spec(
        1.60e-2, 'Table 2 at 2 degC, term b', 'Pa/MPa', -1.0e9, 1.0e9
    )
    alpha_a_25c_pa: float = spec(
        2.01e7, 'Table 2 at 25 degC, term a', 'Pa', 0.0, 1.0e12, low_open=True
    )
    alpha_b_25c_pa_per_mpa: float = spec(
        5.10e-1, 'Table 2 at 25 degC, term b', 'Pa/MPa', -1.0e9, 1.0e9
    )

    def __post_init__(self) -> None:
        """Refuse non-physical oil data."""
        validate(self)
        if not self.nu100_mm2_s < self.nu40_mm2_s:
            raise ValueError(
                'nu100_mm2_s must be below nu40_mm2_s (viscosity falls with temperature)'
            )


def kinematic_viscosity_m2_s(temperature_c: float, oil: OilProperties) -> float:
    """Kinematic viscosity [m^2/s] at ``temperature_c``.

    By ASTM D341 (Walther) through nu40 and nu100.
    """
    log_t40 = math.log10(40.0 + KELVIN_OFFSET)
    log_t100 = math.log10(100.0 + KELVIN_OFFSET)
    w40 = math.log10(math.log10(oil.nu40_mm2_s + 0.7))
    w100 = math.log10(math.log10(oil.nu100_mm2_s + 0.7))
    slope_b = (w40 - w100) / (log_t100 - log_t40)
    intercept_a = w40 + slope_b * log_t40
    walther = intercept_a - slope_b * np.log10(temperature_c + KELVIN_OFFSET)
    nu_mm2_s = 10.0 ** (10.0**walther) - 0.7
    return nu_mm2_s * 1.0e-6


def density_kg_m3(temperature_c: float, oil: OilProperties) -> float:
    """Oil density [kg/m^3] at ``temperature_c``, linear thermal expansion from 15 degC."""
    return oil.density15_kg_m3 / (1.0 + oil.expansion_per_k * (temperature_c - 15.0))


def pressure_viscosity_coefficient_per_pa(
    temperature_c: float, pressure_pa: float, oil: OilProperties
) -> float:
    """Viscosity-pressure coefficient alpha [1/Pa] of Table 2, interpolated in temperature."""
    weight = (temperature_c - 2.0) / (25.0 - 2.0)
    a = oil.alpha_a_2c_pa + weight * (oil.alpha_a_25c_pa - oil.alpha_a_2c_pa)
    b = oil.alpha_b_2c_pa_per_mpa + weight * (
        oil.alpha_b_25c_pa_per_mpa - oil.alpha_b_2c_pa_per_mpa
    )
    denominator = a + b * pressure_pa / PA_PER_MPA
    if np.any(np.asarray(denominator) <= 0.0):
        raise ValueError(
            f'temperature {temperature_c} degC is outside the range where Table 2 extrapolates'
        )
    return 1.0 / denominator


def dynamic_viscosity_pa_s(temperature_c: float, pressure_pa: float, oil: OilProperties) -> float:
    """Dynamic viscosity mu = mu_0(T) * exp(alpha * P) [Pa s], eq. (7).

    With mu_0 = rho * nu at P = 0.
    """
    if np.any(np.asarray(pressure_pa) < 0.0):
        raise ValueError(f'pressure_pa must be >= 0 (gauge), got {pressure_pa}')
    mu0 = density_kg_m3(temperature_c, oil) * kinematic_viscosity_m2_s(temperature_c, oil)
    return mu0 * np.exp(
        pressure_viscosity_coefficient_per_pa(temperature_c, pressure_pa, oil) * pressure_pa
    )


@dataclass(frozen=True)
class MotorGeometry:
    """Motor geometry of Table 3 [m] (d1/d2 swapped, see the module docstring)."""

    rotor_diameter_m: float = spec(37.5e-3, 'd: rotor diameter', 'm', 0.0, 1.0, low_open=True)
    rotor_end_diameter_m: float = spec(37.5e-3, 'd1: rotor end-face diameter', 'm', 0.0, 1.0)
    housing_end_diameter_m: float = spec(63.0e-3, 'd2: housing end-face diameter', 'm', 0.0, 1.0)
    radial_gap_m: float = spec(
        0.3e-3, 'delta: rotor-stator radial gap', 'm', 0.0, 0.1, low_open=True
    )
    end_gap_m: float = spec(
        38.0e-3, 'h: rotor end face to housing end face', 'm', 0.0, 1.0, low_open=True
    )
    rotor_length_m: float = spec(15.5e-3, 'L: rotor length', 'm', 0.0, 1.0)

    def __post_init__(self) -> None:
        """Refuse a geometry that makes a loss term negative."""
        validate(self)
        if self.housing_end_diameter_m < self.rotor_end_diameter_m:
            raise ValueError(
                'housing_end_diameter_m (d2) must be >= rotor_end_diameter_m (d1), eq. (6)'
            )


def stirring_geometry_constant_m3(geometry: MotorGeometry) -> float:
    """Geometry constant k = pi L d^3/(4 delta) + pi (d2^4 - d1^4)/(32 h) [m^3] of eq. (6)."""
    g = geometry
    flank = math.pi * g.rotor_length_m * g.rotor_diameter_m**3 / (4.0 * g.radial_gap_m)
    disk = (
        math.pi * (g.housing_end_diameter_m**4 - g.rotor_end_diameter_m**4) / (32.0 * g.end_gap_m)
    )
    return flank + disk
