# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""docs/reference/parameters.md says what every node declares (generated from the specs)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_parameter_tables_are_current(ros_env):
    done = subprocess.run(
        [sys.executable, '-m', 'actuator_bringup.reference_docs', '--check'],
        cwd=ROOT,
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]


def test_a_changed_table_is_caught(ros_env, tmp_path):
    stale = tmp_path / 'parameters.md'
    current = (ROOT / 'docs/reference/parameters.md').read_text()
    stale.write_text(current.replace('0.05', '0.06', 1))
    done = subprocess.run(
        [sys.executable, '-m', 'actuator_bringup.reference_docs', '--check', '--path', str(stale)],
        cwd=ROOT,
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1 and 'is not current' in done.stderr
