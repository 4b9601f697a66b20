# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``design_gains --joint FILE``: the identified joint (``bag_identify --params``) as the design's.

The nominal model of the observer and the law becomes the identified theta1, theta2. The design's
plant becomes the identified joint, written in the simulated joint's terms (eq. (1), (42)):
  * J = k_t / (theta1 N) with k_t and N Table 1's (only their ratio theta1 is identified; k_t
    matters only through the external torque of eq. (40), given in N m);
  * k_b = -theta2 J, and no separate oil stirring loss (theta2 holds all viscous friction):
    rotor length 0 and equal end-face diameters make eq. (6)'s geometry constant 0;
  * the seal friction of eq. (42) as the identified Coulomb friction: c_p = c_v = 0 leave
    c0 + 2 N m, so c0 = fc J N^2 - 2 (0 when fc J N^2 is below 2 N m, which eq. (42) cannot
    go under); a Stribeck or drag term has no counterpart in eq. (42) and is left out (said).
Around it the design keeps its envelope: the drift of eq. (41) (in the margin, at its vertices)
and the external torque of eq. (40), and, unless --corner says otherwise, ``JOINT_CORNERS``:
no and two samples of command delay.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from actuator_core import limits
from actuator_core.identified import IdentifiedJoint, from_document
from actuator_eso.observer import EsoGains
from actuator_plant.oil import MotorGeometry
from actuator_studies.space import StudyInputError

#: The corners of a design for an identified joint (the drift is the margin's).
JOINT_CORNERS = ('command_delay_samples=0,2',)
#: What eq. (42) adds to c0 when c_p = c_v = 0: e^0 + e^0 [N m].
SEAL_FLOOR_NM = 2.0


def read_joint(path: Path) -> IdentifiedJoint:
    """Read the identified joint of a parameter file; StudyInputError says what is wrong."""
    try:
        return from_document(yaml.safe_load(Path(path).read_text()))
    except (OSError, yaml.YAMLError, ValueError) as exc:
        raise StudyInputError(f'--joint {path}: {exc}') from None


def joint_design(joint: IdentifiedJoint) -> tuple[EsoGains, list[tuple[str, float]], list[str]]:
    """Return the observer's nominal model, the plant's and law's fixed settings, the notes."""
    gear = limits.NOMINAL_GEAR_RATIO
    torque_constant = limits.NOMINAL_TORQUE_CONSTANT_NM_A
    inertia = torque_constant / (joint.theta1 * gear)
    geometry = MotorGeometry()
    seal_nm = joint.coulomb_rad_s2 * inertia * gear * gear
    notes = [
        f'plant: J = {inertia:.4g} kg m^2 from theta1 with k_t = {torque_constant} N m/A, N = '
        f'{gear:g} (Table 1); all viscous friction in k_b, no stirring loss; Coulomb friction '
        f'{seal_nm:.3g} N m at the output as the seal friction of eq. (42)'
    ]
    if seal_nm < SEAL_FLOOR_NM:
        notes.append(
            f'the Coulomb friction {seal_nm:.3g} N m is below the {SEAL_FLOOR_NM:g} N m eq. (42) '
            'cannot go under: the design plant has 2 N m'
        )
    if joint.friction_model != 'coulomb_viscous':
        notes.append(f'the {joint.friction_model} term has no counterpart in eq. (42): left out')
    settings = [
        ('nominal.inertia_kg_m2', inertia),
        ('nominal.torque_constant_nm_a', torque_constant),
        ('nominal.gear_ratio', gear),
        ('nominal.viscous_coefficient_nm_s_rad', max(0.0, -joint.theta2 * inertia)),
        ('geometry.rotor_length_m', 0.0),
        ('geometry.housing_end_diameter_m', geometry.rotor_end_diameter_m),
        ('seal.pressure_coefficient_per_mpa', 0.0),
        ('seal.velocity_coefficient_s_rad', 0.0),
        ('seal.base_nm', max(0.0, seal_nm - SEAL_FLOOR_NM)),
        ('common.theta1n', joint.theta1),
        ('common.theta2n', joint.theta2),
    ]
    return EsoGains(theta1n=joint.theta1, theta2n=joint.theta2), settings, notes
