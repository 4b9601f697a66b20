# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""controller/state of one sample: the law's signals when it ran, NaN when it did not.

Read back from the bytes the node publishes (the codec's own reading; tests/test_wire.py holds
the codec to rclpy's).
"""

from __future__ import annotations

import math

import pytest

from actuator_controller.controller_state import (
    LAW_FIELDS,
    OUTPUT_FIELDS,
    controller_state_fields,
)
from actuator_controller.laws import make_controller
from actuator_controller.reference import make_reference
from actuator_core.assembly import ControlSampleAssembly
from actuator_core.status import Status
from actuator_msgs.msg import ControllerState
from actuator_ros.wire import Codec

pytestmark = pytest.mark.unit
P = 1_000_000  # 1 ms in ns


CODEC = Codec(ControllerState)


def on_the_wire(sample, stamp_ns: int, *counts):
    """Return the message a subscriber gets for ``sample`` (compute time, late, missed)."""
    fields = controller_state_fields(sample, stamp_ns, 'pp_nftsmc_eso', *counts)
    return CODEC.decode(CODEC.encode(fields))


def law_sample():
    """Sample 0 of the fast reference controlled by PP-NFTSMC-ESO, the joint off by 1 mrad."""
    a = ControlSampleAssembly(make_controller('pp_nftsmc_eso'), make_reference('fast'), P)
    a.add_estimate(0, 0.01, -0.5, initial=True)
    return a, a.add_measurement(0, 1e-3)


def test_a_law_sample_carries_every_signal_of_the_law() -> None:
    """Reference, estimate and each output field as computed; the counts and the time as given."""
    a, sample = law_sample()
    assert sample.output is not None
    s = on_the_wire(sample, 3_000_000_007, 2.5e-4, 4, 2)
    assert (s.header.stamp.sec, s.header.stamp.nanosec) == (3, 7)
    assert s.controller_name == 'pp_nftsmc_eso'
    assert s.status == int(sample.status) and s.measured_position_rad == 1e-3
    assert s.current_a == float(sample.current_a) and s.compute_time_s == 2.5e-4
    assert (s.late_samples, s.missed_samples) == (4, 2)
    assert s.reference_position_rad == sample.reference.position_rad
    assert s.reference_velocity_rad_s == sample.reference.velocity_rad_s
    assert s.reference_acceleration_rad_s2 == sample.reference.acceleration_rad_s2
    assert (s.estimated_velocity_rad_s, s.estimated_disturbance_rad_s2) == sample.estimate
    for name in OUTPUT_FIELDS:  # a PI field of a sliding-mode law is NaN in both
        mine, law = getattr(s, name), float(getattr(sample.output, name))
        assert mine == law or (math.isnan(mine) and math.isnan(law)), name
    assert math.isfinite(s.sigma_rad_s) and math.isfinite(s.rho_rad)
    assert s.bounds_kept == bool(sample.output.bounds_kept)
    assert s.saturated == bool(sample.output.saturated)


def test_a_safe_sample_after_a_law_sample_leaves_no_stale_signal() -> None:
    """Every law field NaN, bounds not kept, not saturated."""
    a, sample = law_sample()
    on_the_wire(sample, 0, 0.0, 0, 0)
    safe = a.safe_sample(P, Status.STALE_MEASUREMENT, y=2e-3)
    s = on_the_wire(safe, 1_000_000_000, 0.0, 0, 0)
    assert all(math.isnan(getattr(s, name)) for name in LAW_FIELDS)
    assert not s.bounds_kept and not s.saturated
    assert s.status == int(Status.STALE_MEASUREMENT) and s.current_a == 0.0
    assert s.measured_position_rad == 2e-3


def test_the_output_fields_are_law_fields_the_message_has() -> None:
    """A law field renamed in the message or the law output fails here, not on a robot."""
    assert set(OUTPUT_FIELDS) <= set(LAW_FIELDS)
    assert all(hasattr(ControllerState(), name) for name in LAW_FIELDS)


def test_a_sample_fills_every_field_of_the_message_and_no_other() -> None:
    """A field added to the message or misspelled here fails at once, law sample or safe."""
    a, sample = law_sample()
    safe = a.safe_sample(P, Status.STALE_MEASUREMENT, y=2e-3)
    for s in (sample, safe):
        assert set(controller_state_fields(s, 0, 'pi', 0.0, 0, 0)) == set(CODEC.fields)
