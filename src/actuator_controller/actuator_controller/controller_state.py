# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""controller/state (actuator_msgs/ControllerState) of one control sample, the law's signals."""

from __future__ import annotations

from actuator_core.assembly import ControlSample
from actuator_core.status import Status
from actuator_msgs.msg import ControllerState
from builtin_interfaces.msg import Time

NAN = float('nan')
#: ControllerState fields copied from the law's output (ControlOutput) of a controlled sample.
OUTPUT_FIELDS = (
    'error_rad',
    'rho_rad',
    'lower_bound_rad',
    'upper_bound_rad',
    'z1',
    'z2_rad_s',
    'alpha_rad_s',
    'alpha_dot_rad_s2',
    'sigma_rad_s',
    'u_eq_rad_s2',
    'u_sw_rad_s2',
    'u_b_rad_s2',
    'proportional_a',
    'integral_a',
    'current_unlimited_a',
)
#: ControllerState fields only a control update computes: NaN on a safe-stop sample.
LAW_FIELDS = (
    'reference_position_rad',
    'reference_velocity_rad_s',
    'reference_acceleration_rad_s2',
    'estimated_velocity_rad_s',
    'estimated_disturbance_rad_s2',
) + OUTPUT_FIELDS


def fill_controller_state(
    s: ControllerState,
    sample: ControlSample,
    stamp: Time,
    compute_time_s: float,
    late: int,
    missed: int,
) -> None:
    """Write sample k (its stamp) into ``s``: the law's signals NaN where it did not run."""
    s.header.stamp = stamp
    s.status = int(Status(sample.status))
    s.measured_position_rad = float(sample.y)
    s.current_a = float(sample.current_a)
    s.compute_time_s = compute_time_s
    s.late_samples, s.missed_samples = late, missed
    out = sample.output
    if out is None:
        for name in LAW_FIELDS:
            setattr(s, name, NAN)
        s.bounds_kept = s.saturated = False
        return
    ref = sample.reference
    s.reference_position_rad = float(ref.position_rad)
    s.reference_velocity_rad_s = float(ref.velocity_rad_s)
    s.reference_acceleration_rad_s2 = float(ref.acceleration_rad_s2)
    s.estimated_velocity_rad_s, s.estimated_disturbance_rad_s2 = (
        float(v) for v in sample.estimate
    )
    for name in OUTPUT_FIELDS:
        setattr(s, name, float(getattr(out, name)))
    s.bounds_kept = bool(out.bounds_kept)
    s.saturated = bool(out.saturated)
