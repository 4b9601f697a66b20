# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The joint contract's ROS-free pieces: settings, soft limits, the simulated joint."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from actuator_core import limits
from actuator_core.joint import CommandFreshness, JointSettings, SoftLimits
from actuator_core.params import iter_specs, range_text
from actuator_plant.encoder import Encoder
from actuator_plant.model import JointPlant, PlantParameters
from actuator_plant.sim_joint import SimulatedJoint

ROOT = Path(__file__).resolve().parents[1]
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


def _documented_rows(title_start: str) -> dict[str, tuple[str, str]]:
    """Parameter -> (default cell, description cell) of a node's table in the reference."""
    rows, inside = {}, False
    for line in (ROOT / 'docs' / 'reference' / 'parameters.md').read_text().splitlines():
        if line.startswith('## '):
            inside = line.startswith(title_start)
        elif inside and line.startswith('| `'):
            name, default, description = (c.strip() for c in line.strip('|').split(' | '))
            rows[name.strip('`')] = (default, description.replace('\\|', '|'))
    return rows


@pytest.mark.parametrize('title', ['## Simulated joint', '## CiA 402 driver'])
def test_every_joint_setting_is_documented_as_specified(title):
    """Each node of a joint declares the common settings with their default, unit and range.

    docs/reference/parameters.md is generated from what the nodes declare (tests/test_param_docs.py
    keeps it current); here each row is held against the specification itself.
    """
    rows = _documented_rows(title)
    settings = list(iter_specs(JointSettings))
    assert len(settings) == len(dataclasses.fields(JointSettings))  # every one is spec'd
    for name, f in settings:
        meta = f.metadata
        text = meta['description']
        if not isinstance(f.default, (str, bool)):  # a switch or a name has no range
            text += f' [{meta["unit"] or "-"}], valid {range_text(meta)}'
        default = f'`{f.default!r}`' if f.default != '' else '`""`'
        assert rows[name] == (default, text), name


def test_the_soft_limits_include_their_ends_and_judge_speed_from_an_angle_outside_too():
    """The angle limits are inclusive; the sample after one outside is judged against it."""
    settings = JointSettings(position_min_rad=-1.0, position_max_rad=2.0, velocity_max_rad_s=5.0)
    assert SoftLimits(settings).check(T0, -1.0) == ''
    assert SoftLimits(settings).check(T0, 2.0) == ''
    s = SoftLimits(settings)
    assert 'outside the soft limits' in s.check(T0, 2.5)
    assert 'speed 500.00 rad/s over 1 ms' in s.check(T0 + P, 2.0)


def test_the_speed_base_is_the_newest_sample_at_least_the_window_old():
    """Samples at 0, 30 and 50 ms with a 20 ms window: 30 ms is the base (exactly 20 ms old)."""
    assert SoftLimits(JointSettings(), window_s=1.0).window_ns == 1_000_000_000
    s = SoftLimits(JointSettings(velocity_max_rad_s=20.0))
    assert s.check(T0, 0.0) == '' and s.check(T0 + 30 * P, 0.0) == ''
    # 0.5 rad over 20 ms is 25 rad/s; over the 50 ms since the first sample it would be 10.
    assert s.check(T0 + 50 * P, 0.5) == (
        'joint speed 25.00 rad/s over 20 ms beyond the soft limit 20 rad/s'
    )


def test_a_repeated_stamp_has_no_speed():
    """The same instant twice (a replayed sample) divides by nothing and trips nothing."""
    s = SoftLimits(JointSettings())
    assert s.check(T0, 0.1) == '' and s.check(T0, 0.1) == ''


# --- loop health: CommandFreshness -------------------------------------------------------------


def test_freshness_degrades_below_the_share_and_recovers_above_it_plus_the_hysteresis():
    f = CommandFreshness(4, 0.5)  # healthy again at 0.6
    got = [f.add(fresh) for fresh in (True, True, False)]
    assert got == ['', '', ''] and f.share is None  # the window is not full yet
    assert f.add(False) == '' and f.share == 0.5  # at the minimum: not below it
    assert f.add(False) == 'degraded' and f.share == 0.25 and f.degraded
    assert [f.add(fresh) for fresh in (False, True, True)] == ['', '', '']  # 0, 0.25, 0.5
    assert f.degraded and f.share == 0.5  # back at the minimum is not healthy yet
    assert f.add(True) == 'healthy' and f.share == 0.75 and not f.degraded
    assert f.add(False) == '' and f.episodes == 1 and f.fresh == 3
    assert f.degraded is False  # a bool for /diagnostics, not merely falsy
    assert [f.add(False) for _ in range(2)] == ['', 'degraded'] and f.episodes == 2


def test_freshness_counts_from_the_first_fresh_command_and_forgets_at_reset():
    f = CommandFreshness(3, 0.5)
    assert all(f.add(False) == '' for _ in range(10))  # no command yet: the loop is not closed
    assert f.share is None and f.fresh == 0
    assert [f.add(x) for x in (True, False, False)] == ['', '', 'degraded']
    assert f.episodes == 1
    f.reset()
    assert (f.share, f.fresh, f.degraded, f.episodes) == (None, 0, False, 0)
    assert f.add(False) == '' and f.share is None


def test_freshness_at_0_never_degrades_and_at_1_needs_every_sample():
    never = CommandFreshness(2, 0.0)
    assert [never.add(x) for x in (True, False, False, False)] == ['', '', '', '']
    assert never.share == 0.0 and not never.degraded
    strict = CommandFreshness(2, 1.0)  # healthy again at 1.0 (capped), not 1.1
    assert strict.share_healthy == 1.0
    assert [strict.add(x) for x in (True, True, False, True, True)] == [
        '',
        '',
        'degraded',
        '',
        'healthy',
    ]


def test_freshness_refuses_an_empty_window_or_a_share_outside_0_1():
    for window, share in ((0, 0.5), (1, -0.01), (1, 1.01), (1, math.nan)):
        with pytest.raises(ValueError, match='window'):
            CommandFreshness(window, share)
    assert CommandFreshness(1, 0.0).window == 1


def test_freshness_describes_the_share_against_its_minimum():
    f = CommandFreshness(4, 0.5)
    assert f.describe() == 'fresh commands not judged yet of the last 4 samples (minimum 50%)'
    for x in (True, False, False, False):
        f.add(x)
    assert f.describe() == 'fresh commands 25.0% of the last 4 samples (minimum 50%)'


def test_a_joint_ends_control_by_default_with_0_a_and_the_brake_and_says_so():
    """Joint.end_control's default: one write of 0 A with the brake; describe adds nothing."""
    from actuator_core.joint import Joint

    class Recorded(Joint):
        """The smallest joint: it records its writes."""

        def __init__(self):
            self.writes = []

        def write(self, current_a, brake):
            self.writes.append((current_a, brake))

        def read(self, stamp_ns):
            return None

    joint = Recorded()
    assert joint.end_control('joint angle outside the soft limits') == '0 A, brake engaged'
    assert joint.writes == [(0.0, True)]
    assert joint.describe() == ''


def test_a_plant_node_s_values_give_its_joint_at_the_named_condition_and_depth():
    """plant_from_values: dotted parameters, the named condition, a depth's pressure."""
    from actuator_plant.model import DEFAULT_DEPTH_M, WorkingCondition, plant_from_values

    lab = plant_from_values({'working_condition': 'lab', 'seal.base_nm': 0.5})
    assert lab.condition == WorkingCondition.lab() and lab.seal.base_nm == 0.5
    assert plant_from_values({}).condition == WorkingCondition.deep_sea()
    deep = plant_from_values({'working_condition': 'depth', 'depth_m': 500.0})
    assert deep.condition == WorkingCondition.at_depth(500.0)
    assert deep.condition != WorkingCondition.at_depth(DEFAULT_DEPTH_M)
    warm = plant_from_values({'working_condition': 'depth', 'condition.temperature_c': 20.0})
    assert warm.condition == WorkingCondition.at_depth(DEFAULT_DEPTH_M, 20.0)
