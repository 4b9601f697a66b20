# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``bag_identify`` on bags of a joint of known truth, and bag_analyze's b0 row.

The bags as the recorder and ``ros2 bag record`` write them: estimates, JSON, parameter file,
current sources, refusals.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import yaml

from actuator_analysis.identify_cli import main
from actuator_controller.laws import CommonConfig
from actuator_core.identified import from_document
from actuator_eso.observer import EsoGains
from identify_helpers import (
    OBSERVER_THETA1N,
    TORQUE_PER_AMP,
    Truth,
    synthetic_joint,
    write_identification_bag,
)

pytestmark = pytest.mark.slow


@pytest.fixture(scope='module')
def run():
    return synthetic_joint(Truth())


@pytest.fixture(scope='module')
def bags(run, tmp_path_factory):
    """Write the run as the project's recorder writes it, and as ros2 bag record does (MCAP)."""
    root = tmp_path_factory.mktemp('bags')
    return {
        style: write_identification_bag(root / style, run, style)
        for style in ('project', 'rosbag2')
    }


def _identify(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_both_bag_formats_give_the_same_estimates_and_the_json_holds_them(
    bags, run, tmp_path, capsys
):
    docs = {}
    for style, bag in bags.items():
        code, out, err = _identify(capsys, bag, '--json', tmp_path / f'{style}.json')
        assert code == 0, err
        assert 'current: ' in out and 'plant/truth current_a' in out
        assert 'not J, k_t or k_b separately' in out  # what a run of angle and current can give
        docs[style] = json.loads((tmp_path / f'{style}.json').read_text())
    assert docs['project']['estimates'] == docs['rosbag2']['estimates']
    doc = docs['project']
    theta1 = doc['estimates']['theta1']
    assert theta1['low'] <= run.truth.theta1 <= theta1['high']
    assert theta1['unit'] == 'rad/s^2/A'
    assert doc['friction_model'] == 'drag'
    assert set(doc['models']) == {'coulomb_viscous', 'stribeck', 'drag'}
    assert doc['held_out']['velocity_r2'] > 0.999 and doc['held_out']['blocks'] == 3
    assert doc['current_sources'] == {str(bags['project']): 'plant/truth current_a'}


def test_the_parameter_file_sets_both_nodes_nominal_model(bags, run, tmp_path, capsys):
    params = tmp_path / 'joint.yaml'
    code, out, err = _identify(capsys, bags['project'], '--params', params)
    assert code == 0, err
    doc = yaml.safe_load(params.read_text())
    eso = doc['actuator_eso']['ros__parameters']
    common = doc['actuator_controller']['ros__parameters']['common']
    assert eso == common
    assert abs(eso['theta1n'] / run.truth.theta1 - 1.0) < 1e-3
    # every key is a parameter the nodes declare (EsoGains, CommonConfig refuse unknown ones)
    assert EsoGains(**eso).theta1n == eso['theta1n']
    assert CommonConfig(**common).theta2n == common['theta2n']
    joint = from_document(doc)
    assert joint.friction_model == 'drag'
    assert joint.theta1_low <= run.truth.theta1 <= joint.theta1_high
    assert joint.drag_per_rad == pytest.approx(run.truth.drag_per_rad, rel=0.01)
    assert params.read_text().startswith('# Identified by bag_identify from ')


def test_without_the_truth_the_effort_or_the_command_gives_the_current(run, tmp_path, capsys):
    bag = write_identification_bag(tmp_path / 'no_truth', run, kinds=('joint', 'state', 'command'))
    code, out, _ = _identify(capsys, bag, '--torque-per-amp', TORQUE_PER_AMP, '-q')
    assert code == 0
    by_effort = float(out.split('theta1')[1].split()[0])
    code, out, _ = _identify(capsys, bag)
    assert code == 0
    assert 'current_command' in out and 'commanded a sample earlier' in out
    by_command = float(out.split('\ntheta1')[1].split()[0])
    for value in (by_effort, by_command):  # the command is what the joint held one sample later
        assert abs(value / run.truth.theta1 - 1.0) < 1e-3


def test_bad_input_is_refused_with_one_line_and_exit_2(bags, run, tmp_path, capsys):
    only_angle = write_identification_bag(tmp_path / 'angle', run, kinds=('joint',))
    code, _, err = _identify(capsys, only_angle)
    assert (code, err) == (
        2,
        f'bag_identify: error: {only_angle}: no current to identify from: the bag has no '
        'plant/truth, no current_command, and joint_states effort needs --torque-per-amp\n',
    )
    no_joint = write_identification_bag(tmp_path / 'no_joint', run, kinds=('truth',))
    code, _, err = _identify(capsys, no_joint)
    assert code == 2 and err.startswith(f'bag_identify: error: {no_joint}: no sensor_msgs/msg/')
    broken = tmp_path / 'broken'
    shutil.copytree(bags['rosbag2'], broken)
    (mcap,) = broken.glob('*.mcap')
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    code, _, err = _identify(capsys, broken)
    assert code == 2 and err.count('\n') == 1 and err.startswith('bag_identify: error: ')
    code, _, err = _identify(capsys, tmp_path / 'missing')
    assert (code, err) == (
        2,
        f'bag_identify: error: {tmp_path / "missing"}: no such bag (the path does not exist)\n',
    )
    short = write_identification_bag(tmp_path / 'short', synthetic_joint(duration_s=6.0))
    code, _, err = _identify(capsys, short)
    assert code == 2 and err.startswith('bag_identify: error: refused: too little data: ')
    code, _, err = _identify(capsys, bags['project'], '--cutoff', 'nan')
    assert (code, err) == (2, 'bag_identify: error: --cutoff must be finite and > 0\n')


def test_figures_are_drawn(bags, tmp_path, capsys):
    code, out, _ = _identify(capsys, bags['project'], '--out', tmp_path / 'figures')
    assert code == 0
    for name in ('identify_held_out.png', 'identify_friction.png'):
        path = tmp_path / 'figures' / name
        assert path.stat().st_size > 10_000 and path.read_bytes()[:4] == b'\x89PNG'


def test_bag_analyze_says_how_far_b0_is_from_the_joint(bags, run, capsys):
    from actuator_analysis.cli import main as analyze

    assert analyze([str(bags['project']), '-q']) == 0
    (row,) = [line for line in capsys.readouterr().out.splitlines() if line.startswith('b0 ')]
    seen = float(row.split('joint ')[1].split()[0])
    assert abs(seen / run.truth.theta1 - 1.0) < 0.01
    relative = 100 * (seen / OBSERVER_THETA1N - 1.0)
    assert f'{relative:+.1f} % from theta1n {OBSERVER_THETA1N:.4g}' in row
    assert row.endswith('identify the joint (bag_identify)')


def test_b0_mismatch_tells_a_drifting_joint():
    from actuator_analysis.mismatch import b0_mismatch

    drifting = synthetic_joint(Truth(theta1_drift=(0.3, 0.94)))
    figures = b0_mismatch(
        drifting.position_rad,
        drifting.current_held_a,
        1e-3,
        np.ones(len(drifting.position_rad), bool),
        OBSERVER_THETA1N,
    )
    assert figures.windows == 6
    assert figures.window_high / figures.window_low > 1.3  # theta1 (1 +- 0.3) over the windows
