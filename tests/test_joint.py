# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The joint contract's ROS-free pieces: settings, soft limits, the simulated joint."""

import numpy as np
import pytest

from actuator_core import limits
from actuator_core.joint import JointSettings, SoftLimits
from actuator_plant.encoder import Encoder
from actuator_plant.model import JointPlant, PlantParameters
from actuator_plant.sim_joint import SimulatedJoint

P = 1_000_000  # 1 ms in ns
T0 = 5_000 * P  # stamp of sample 0 of a run


def test_soft_limits_refuse_an_angle_outside_and_a_speed_beyond():
    s = SoftLimits(
        JointSettings(position_min_rad=-1.0, position_max_rad=2.0, velocity_max_rad_s=5.0)
    )
    assert s.check(0, 0.0) == '' and s.check(P, 0.004) == ''  # 4 rad/s
    assert 'speed 6.00 rad/s beyond the soft limit 5' in s.check(2 * P, 0.010)
    s.reset()
    assert s.check(10 * P, 1.0) == ''  # after a reset the first sample has no speed
    assert 'outside the soft limits [-1, 2] rad' in s.check(11 * P, 2.0001)
    assert 'outside the soft limits' in s.check(12 * P, -1.5)


def test_joint_settings_refuse_an_empty_window_and_a_zero_current_limit():
    with pytest.raises(ValueError, match='must be below position_max_rad'):
        JointSettings(position_min_rad=1.0, position_max_rad=1.0)
    with pytest.raises(ValueError, match='current_limit_a = 0.0 is outside'):
        JointSettings(current_limit_a=0.0)


def test_the_simulated_joint_is_the_plant_model_one_sample_per_read():
    params, dt = PlantParameters(), limits.SAMPLE_TIME_S
    joint, plant = SimulatedJoint(params, dt, position_rad=0.1), JointPlant(params, dt, 0.1)
    joint.activate()
    first = joint.read(T0)  # the first read after activation only samples
    assert first.position_rad == 0.1 and first.effort_nm == 0.0
    for k, (u, brake) in enumerate([(3.0, False), (-2.0, False), (0.0, True), (1.0, False)]):
        joint.write(u, brake)
        sample = joint.read(T0 + (k + 1) * P)
        plant.step(u, brake)
        assert sample.position_rad == plant.position_rad  # bit for bit the model
        assert sample.effort_nm == pytest.approx(
            u * params.nominal.torque_constant_nm_a * params.nominal.gear_ratio
        )
        assert joint.brake is brake and sample.stamp_ns == T0 + (k + 1) * P


def test_the_simulated_joints_drive_effects_delay_smooth_and_quantise():
    params, dt = PlantParameters(), limits.SAMPLE_TIME_S
    late = SimulatedJoint(params, dt, command_delay_samples=2)
    late.activate()
    late.read(0)
    applied = []
    for k, u in enumerate([5.0, 6.0, 7.0, 8.0]):
        late.write(u, False)
        late.read((k + 1) * P)
        applied.append(late.applied_a)
    assert applied == [0.0, 0.0, 5.0, 6.0]  # u(k - 2)
    smooth = SimulatedJoint(params, dt, torque_time_constant_s=2e-4)
    smooth.activate()
    smooth.read(0)
    smooth.write(10.0, False)
    smooth.read(P)
    assert 8.0 < smooth.applied_a < 10.0  # the mean over the first sample of a 0.2 ms loop
    coarse = SimulatedJoint(params, dt, position_rad=0.0123, encoder=Encoder(counts_per_rev=1000))
    coarse.activate()
    assert coarse.read(0).position_rad == pytest.approx(2 * np.pi / 1000 * 2)  # counts, not q
