# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Values before stamps: every field of an input against its physical bound, in one place.

A receiver checks a measurement's, an estimate's or a command's values before it looks at the
stamp, so a refused value never moves a stream's newest stamp
(docs/safety.md#values-before-stamps).
Each function returns why a value is refused, or '' when it is physical; the bounds are
``actuator_core.limits``'. The joint's gate applies the same bound to a command elementwise
(``actuator_core.gate``).
"""

from __future__ import annotations

import math
from typing import Optional

from actuator_core import limits


def within(value: float, bound: float) -> bool:
    """Return whether ``value`` is finite and within +-``bound``."""
    return math.isfinite(value) and abs(value) <= bound


def measurement_problem(y: Optional[float], joint_name: str, positions) -> str:
    """Why a joint_states measurement is refused ('' when its angle is physical)."""
    if y is not None and within(y, limits.POSITION_LIMIT_RAD):
        return ''
    return (
        f'measurement refused (joint {joint_name!r} missing, non-finite or beyond '
        f'{limits.POSITION_LIMIT_RAD} rad): {list(positions)}'
    )


def command_problem(current_a: float, current_limit_a: float) -> str:
    """Why a command's current is refused by the observer ('' when within the limit)."""
    if within(current_a, current_limit_a):
        return ''
    return f'command {current_a} A refused (non-finite or beyond {current_limit_a} A)'


def estimate_problem(x2, x3, u, gain, current_limit_a: float, dt_s: float) -> tuple[str, str]:
    """Return (field, why) when an estimate's field is not physical, else ('', '')."""
    checks = (
        ('velocity_rad_s', x2, limits.VELOCITY_LIMIT_RAD_S),
        ('disturbance_rad_s2', x3, limits.DISTURBANCE_LIMIT_RAD_S2),
        ('input_current_a', u, current_limit_a),
        ('input_current_gain', gain, limits.input_current_gain_limit(dt_s)),
    )
    for name, value, bound in checks:
        if not within(value, bound):
            return name, f'{name} = {value} is not finite or beyond +-{bound:g}'
    if gain < 0.0:
        return 'input_current_gain', f'input_current_gain = {gain} is negative'
    return '', ''
