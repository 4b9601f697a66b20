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
    assert s.check(2 * P, 0.010) == ''  # 6 rad/s in this sample, 5 over the window so far
    assert 'speed 5.33 rad/s over 3 ms beyond the soft limit 5' in s.check(3 * P, 0.016)
    s.reset()
    assert s.check(10 * P, 1.0) == ''  # after a reset the first sample has no speed
    assert 'outside the soft limits [-1, 2] rad' in s.check(11 * P, 2.0001)
    assert 'outside the soft limits' in s.check(12 * P, -1.5)


def test_the_soft_speed_limit_judges_a_window_not_a_lagging_sample():
    """Feedback that lags 28 samples and catches up in one is no overspeed; 25 rad/s is.

    At 5 rad/s the catch-up sample alone implies 145 rad/s (what ended control of the CiA 402
    loop on a loaded host); over the 20 ms window it is the true speed plus the lag's share.
    """
    assert limits.SOFT_VELOCITY_WINDOW_S == 0.02
    windowed, one_sample = SoftLimits(JointSettings()), SoftLimits(JointSettings(), 0.0)
    tripped = []
    for k in range(100):
        y = 5.0 * (39 if 40 <= k < 68 else k) * 1e-3  # the position of sample 39 until 68
        assert windowed.check(k * P, y) == '', k
        if one_sample.check(k * P, y):
            tripped.append(k)
    assert tripped[:1] == [68]  # judged sample by sample, the catch-up is 145 rad/s
    fast = SoftLimits(JointSettings())
    verdicts = [fast.check(k * P, 25.0 * k * 1e-3) for k in range(30)]
    assert verdicts[0] == '' and 'speed 25.00 rad/s over 1 ms' in verdicts[1]
    rising = SoftLimits(JointSettings())  # a runaway from 10 rad/s at 1000 rad/s^2
    y, speed, tripped = 0.0, 10.0, None
    for k in range(200):
        y += speed * 1e-3
        speed += 1000.0 * 1e-3
        if rising.check(k * P, y):
            tripped = speed
            break
    assert tripped is not None and tripped <= 20.0 + 1000.0 * limits.SOFT_VELOCITY_WINDOW_S


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
