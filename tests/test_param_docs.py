# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""docs/reference/ says what the code declares: parameters, nodes, topics, launch, tools."""

import shutil
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
    shutil.copytree(ROOT / 'docs' / 'reference', tmp_path / 'docs' / 'reference')
    stale = tmp_path / 'docs' / 'reference' / 'parameters.md'
    stale.write_text(stale.read_text().replace('0.05', '0.06', 1))
    done = subprocess.run(
        [sys.executable, '-m', 'actuator_bringup.reference_docs', '--check', '--root', tmp_path],
        cwd=ROOT,
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1
    assert done.stderr.startswith('not current: docs/reference/parameters.md: run '), done.stderr


def _tables(text: str) -> dict[str, dict[str, str]]:
    """{node section: {parameter: description}} of the generated reference."""
    out: dict[str, dict[str, str]] = {}
    section = ''
    for line in text.splitlines():
        if line.startswith('## '):
            section = line[3:]
            out[section] = {}
        elif line.startswith('| `') and section:
            cells = [c.strip() for c in line.strip('|').split(' | ')]
            out[section][cells[0].strip('`')] = cells[2]
    return out


def test_every_parameter_name_has_one_description_and_range_wherever_it_is_declared():
    """A name several nodes declare (the loop's shared ones above all) means one thing."""
    tables = _tables((ROOT / 'docs/reference/parameters.md').read_text())
    assert len(tables) >= 4, list(tables)
    seen: dict[str, dict[str, list[str]]] = {}
    for section, rows in tables.items():
        for name, description in rows.items():
            seen.setdefault(name, {}).setdefault(description, []).append(section)
    differing = {name: texts for name, texts in seen.items() if len(texts) > 1}
    assert not differing, differing
    shared = [n for n, texts in seen.items() if sum(len(s) for s in texts.values()) > 1]
    assert {'sample_time_s', 'current_limit_a', 'mode', 'joint_name'} <= set(shared)
