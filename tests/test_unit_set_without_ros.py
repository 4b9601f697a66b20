# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The unit set (``-m unit``) collects and runs with rclpy and launch unimportable.

Each pytest here runs in a subprocess whose sitecustomize puts a meta-path finder in front that
answers ModuleNotFoundError for rclpy, launch and launch_ros, as on a machine without ROS.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # three pytest subprocesses

REPO = Path(__file__).resolve().parents[1]
BLOCKER = '''
import sys


class _NoRos:
    """Answer as if rclpy, launch and launch_ros were not installed."""

    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('rclpy', 'launch', 'launch_ros'):
            raise ModuleNotFoundError(f'No module named {name!r} (blocked)', name=name)
        return None


sys.meta_path.insert(0, _NoRos())
'''
#: The modules that imported rclpy or launch for their unit tests, and a pure one.
ONCE_BROKEN = ('test_bench.py', 'test_bag_record.py', 'test_msgs.py', 'test_closed_loop_nodes.py')


def _pytest(args, blocked: Path | None, timeout: float = 300):
    env = dict(os.environ)
    if blocked is not None:
        env['PYTHONPATH'] = os.pathsep.join([str(blocked), env.get('PYTHONPATH', '')])
    return subprocess.run(
        [sys.executable, '-m', 'pytest', '-p', 'no:cacheprovider', *args],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def _collected(output: str) -> int:
    match = re.search(r'(\d+)(?:/\d+)? tests? collected', output)
    assert match, output[-2000:]
    return int(match.group(1))


@pytest.fixture
def blocked(tmp_path) -> Path:
    (tmp_path / 'sitecustomize.py').write_text(BLOCKER)
    probe = subprocess.run(
        [sys.executable, '-c', 'import rclpy'],
        env={**os.environ, 'PYTHONPATH': str(tmp_path)},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert probe.returncode != 0 and 'blocked' in probe.stderr, probe.stderr  # it does block
    return tmp_path


def test_unit_set_collects_the_same_tests_without_rclpy_and_launch(blocked):
    without = _pytest(['-m', 'unit', '--collect-only', '-q'], blocked)
    assert without.returncode == 0, without.stdout[-3000:] + without.stderr[-2000:]
    assert 'error' not in without.stdout.lower().split('collected')[-1]
    usual = _pytest(['-m', 'unit', '--collect-only', '-q'], None)
    assert usual.returncode == 0
    assert _collected(without.stdout) == _collected(usual.stdout) > 200


def test_unit_tests_of_the_modules_that_needed_ros_run_without_it(blocked):
    run = _pytest(['-m', 'unit', '-q', *(f'tests/{m}' for m in ONCE_BROKEN)], blocked)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    passed = re.search(r'(\d+) passed', run.stdout)
    assert passed and int(passed.group(1)) >= 10 and 'skipped' not in run.stdout.splitlines()[-1]
