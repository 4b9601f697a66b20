# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What every reference gives at a time: x1d and its first two derivatives (ReferenceSample).

Its own module, below the references: the paper's ones and the factory ``make_reference``
(``reference``), the commanded one (``commanded_reference``) and the excitation (``excitation``)
all import it, and the factory imports the other two.
"""

from __future__ import annotations

from typing import NamedTuple

from actuator_core.xmath import FloatOrArray


class ReferenceSample(NamedTuple):
    """Desired position x1d [rad], velocity [rad/s] and acceleration [rad/s^2] at one time."""

    position_rad: FloatOrArray
    velocity_rad_s: FloatOrArray
    acceleration_rad_s2: FloatOrArray
