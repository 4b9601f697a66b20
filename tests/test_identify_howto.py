# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""docs/how-to/identify-a-joint.md followed word for word on its simulated joint.

The page's ```yaml block is the joint file it names; each line of its ```sh blocks runs as written
in bash (``ros2 run PKG EXE`` resolved as ros2cli does, through the ament index: ros2cli is not
installed here), in order, in one folder and one ROS domain, with the exit status the line's
comment states (0 otherwise). The ```text blocks after a command are its output: the runs are in
sim time, deterministic, so they must match (less the lines naming a bag's time stamp).
"""

from __future__ import annotations

import json
import math
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / 'docs' / 'how-to' / 'identify-a-joint.md'
#: What ``ros2 run`` does, here where ros2cli is not installed (scripts/ros2run's lookup).
ROS2 = (
    'ros2() { [ "$1" = run ] || return 2; local exe; '
    'exe=$(python -m actuator_bringup.supervisor which "$2" "$3") || return 2; shift 3; '
    '"$exe" "$@"; }\n'
)
#: theta1 of the page's joint: k_t / (J N).
THETA1 = 0.0945 / (4.7e-5 * 100.0)

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced block, in order."""
    return re.findall(r'```(\w+)\n(.*?)```', text, flags=re.S)


def commands(body: str) -> list[tuple[str, int]]:
    """(line, expected exit status) of a sh block."""
    out = []
    for line in body.splitlines():
        if not line.strip() or line.lstrip().startswith('#'):
            continue
        status = re.search(r'#\s*exit status (\d+)\s*$', line)
        out.append((line, int(status.group(1)) if status else 0))
    return out


def test_the_page_runs_as_written(ros_env, tmp_path):
    page = blocks(PAGE.read_text())
    (joint,) = [body for language, body in page if language == 'yaml']
    assert 'my_joint.yaml' in PAGE.read_text().split('```yaml')[0][-300:]  # the file it names
    (tmp_path / 'my_joint.yaml').write_text(joint)
    ran = []
    for i, (language, body) in enumerate(page):
        if language != 'sh':
            continue
        for line, expected in commands(body):
            done = subprocess.run(
                ['bash', '-c', ROS2 + line],
                cwd=tmp_path,
                env=ros_env,
                capture_output=True,
                text=True,
                timeout=900,
            )
            assert done.returncode == expected, (line, done.stdout[-2000:], done.stderr[-2000:])
            ran.append((line, done, i))
        following = page[i + 1] if i + 1 < len(page) else ('', '')
        if following[0] == 'text':  # the output of the block's last command, as the page shows it
            _, done, _ = ran[-1]
            shown = [x for x in following[1].splitlines() if 'excitation_sim_2' not in x]
            printed = (done.stdout + done.stderr).splitlines()
            missing = [x for x in shown if x not in printed]
            assert not missing, (ran[-1][0], missing, printed)
    assert len(ran) == 7
    # what the page says about the outcome holds for this run
    doc = json.loads((tmp_path / 'identified.json').read_text())
    theta1 = doc['estimates']['theta1']
    assert theta1['low'] <= THETA1 <= theta1['high']
    (analysis,) = [done.stdout for line, done, _ in ran if 'bag_analyze' in line]
    assert 'joint 20.01 rad/s^2/A, -36.4 % from theta1n 31.44' in analysis
    assert '-0.1 % from theta1n 20.1 ' in analysis
    assert (tmp_path / 'figures' / 'identify_held_out.png').stat().st_size > 10_000
    design = json.loads((tmp_path / 'design' / 'design.json').read_text())
    assert design['joint']['file'] == 'my_joint_identified.yaml'
    assert design['comparison']['paper (Table 4)']['radius_by_delay']['2'] > 1.0
    _joint_file_reached_the_plant(tmp_path)


def _joint_file_reached_the_plant(folder: Path) -> None:
    """Check that the angle came through the 16-bit encoder and the current from the plant."""
    from actuator_analysis.identify_data import load_bag

    (bag,) = (folder / 'bags' / 'identify').iterdir()
    samples = load_bag(bag)
    counts = samples.position_rad / (2.0 * math.pi / 65536)
    assert np.allclose(counts, np.round(counts), atol=1e-6)
    assert samples.source == 'plant/truth current_a'
