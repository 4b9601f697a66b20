# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""controller/state (actuator_msgs/ControllerState) of one control sample, the law's signals.

The fields are the wire codec's (actuator_ros.wire): the node encodes them without building a
message object.
"""

from __future__ import annotations

from actuator_core.assembly import ControlSample

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


def controller_state_fields(
    sample: ControlSample,
    stamp_ns: int,
    controller_name: str,
    compute_time_s: float,
    late: int,
    missed: int,
) -> dict:
    """Return sample k's ControllerState as codec fields (law signals NaN where it did not run)."""
    fields = {
        'header.stamp': stamp_ns,
        'header.frame_id': '',
        'controller_name': controller_name,
        'status': int(sample.status),
        'measured_position_rad': float(sample.y),
        'current_a': float(sample.current_a),
        'compute_time_s': compute_time_s,
        'late_samples': late,
        'missed_samples': missed,
    }
    out = sample.output
    if out is None:
        fields.update(SAFE_FIELDS)
        return fields
    ref = sample.reference
    fields['reference_position_rad'] = float(ref.position_rad)
    fields['reference_velocity_rad_s'] = float(ref.velocity_rad_s)
    fields['reference_acceleration_rad_s2'] = float(ref.acceleration_rad_s2)
    assert sample.estimate is not None  # the law ran on one
    velocity, disturbance = sample.estimate
    fields['estimated_velocity_rad_s'] = float(velocity)
    fields['estimated_disturbance_rad_s2'] = float(disturbance)
    for name in OUTPUT_FIELDS:
        fields[name] = float(getattr(out, name))
    fields['bounds_kept'] = bool(out.bounds_kept)
    fields['saturated'] = bool(out.saturated)
    return fields


#: The fields of a sample the law did not run on (a safe stop): no signal, no bound kept.
SAFE_FIELDS = {**dict.fromkeys(LAW_FIELDS, NAN), 'bounds_kept': False, 'saturated': False}
