# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""An identified joint in a ROS 2 parameter file: the one description its writer and readers share.

``bag_identify --params FILE`` writes the nominal model the observer and the law load
(``actuator_eso: theta1n, theta2n``, ``actuator_controller: common.theta1n, common.theta2n``) and,
in a section no node is named after (``SECTION``, which rcl reads and leaves unused), the whole
identified model with its intervals: ``IdentifiedJoint``. ``design_gains --joint FILE`` reads that
section back. Figures per inertia only: J and k_t are not identifiable from angle and current.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from actuator_core.params import spec, validate

#: The parameter-file section of the identified model (no node of the suite has this name).
SECTION = 'identified_joint'
#: The node sections the nominal model goes to, and the parameter names there.
ESO_SECTION, CONTROLLER_SECTION = 'actuator_eso', 'actuator_controller'
FRICTION_MODELS = ('coulomb_viscous', 'stribeck', 'drag')


@dataclass(frozen=True)
class IdentifiedJoint:
    """The identified model q'' = theta1 i + theta2 q' - f(q') + c, 95 % intervals (identify)."""

    friction_model: str = 'coulomb_viscous'
    theta1: float = spec(
        1.0, 'theta1 = k_t/(J N) (eq. (2))', 'rad/s^2/A', 0.0, 1.0e6, low_open=True
    )
    theta1_low: float = spec(
        1.0, 'theta1: low end of its 95 % interval', 'rad/s^2/A', -1.0e6, 1.0e6
    )
    theta1_high: float = spec(
        1.0, 'theta1: high end of its 95 % interval', 'rad/s^2/A', -1.0e6, 1.0e6
    )
    theta2: float = spec(
        0.0, 'theta2: all viscous friction per inertia (motor, oil, seal)', '1/s', -1.0e4, 1.0e4
    )
    theta2_low: float = spec(0.0, 'theta2: low end of its 95 % interval', '1/s', -1.0e5, 1.0e5)
    theta2_high: float = spec(0.0, 'theta2: high end of its 95 % interval', '1/s', -1.0e5, 1.0e5)
    coulomb_rad_s2: float = spec(0.0, 'fc: Coulomb friction per inertia', 'rad/s^2', -1.0e6, 1.0e6)
    offset_rad_s2: float = spec(0.0, 'c: constant load per inertia', 'rad/s^2', -1.0e6, 1.0e6)
    stribeck_rad_s2: float = spec(
        0.0, 'fs: Stribeck excess at rest (stribeck model; else 0)', 'rad/s^2', -1.0e6, 1.0e6
    )
    stribeck_velocity_rad_s: float = spec(
        0.0, 'vs: Stribeck velocity (stribeck model; else 0)', 'rad/s', 0.0, 1.0e3
    )
    drag_per_rad: float = spec(
        0.0, "fd: drag fd q'|q'| per inertia (drag model; else 0)", '1/rad', -1.0e6, 1.0e6
    )
    held_out_velocity_r2: float = spec(
        0.0, 'r^2 of the simulated velocity on the held-out data', '', -1.0e9, 1.0
    )
    sample_time_s: float = spec(1.0e-3, 'sample time of the identified run', 's', 0.0, 1.0)

    def __post_init__(self) -> None:
        """Refuse a friction model the suite does not know and out-of-range figures."""
        if self.friction_model not in FRICTION_MODELS:
            raise ValueError(
                f'friction_model must be one of {", ".join(FRICTION_MODELS)}: '
                f'{self.friction_model!r}'
            )
        validate(self)


def parameters_document(joint: IdentifiedJoint) -> dict:
    """Return the parameter file's content: the nodes' nominal model, the identified section."""
    nominal = {'theta1n': float(joint.theta1), 'theta2n': float(joint.theta2)}
    return {
        ESO_SECTION: {'ros__parameters': dict(nominal)},
        CONTROLLER_SECTION: {'ros__parameters': {'common': dict(nominal)}},
        SECTION: {'ros__parameters': _plain(dataclasses.asdict(joint))},
    }


def from_document(document: Any) -> IdentifiedJoint:
    """Return the IdentifiedJoint of a parameter file's content; ValueError says what is wrong."""
    try:
        values = document[SECTION]['ros__parameters']
    except (KeyError, TypeError):
        raise ValueError(f'no {SECTION} section (write one with bag_identify --params)') from None
    known = {f.name for f in dataclasses.fields(IdentifiedJoint)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise ValueError(f'{SECTION}: unknown parameter(s) {", ".join(unknown)}')
    try:
        return IdentifiedJoint(**values)
    except TypeError as err:
        raise ValueError(f'{SECTION}: {err}') from None


def _plain(values: dict) -> dict:
    """Floats as Python floats (a YAML file of numpy scalars is not one rcl reads)."""
    return {k: (v if isinstance(v, str) else float(v)) for k, v in values.items()}
