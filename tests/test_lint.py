# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Static checks: no unused imports, undefined names or other pyflakes findings in the project's Python."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_pyflakes_finds_nothing():
    files = sorted(
        str(p) for p in (ROOT / 'src').rglob('*.py') if 'build' not in p.parts
    ) + sorted(str(p) for p in (ROOT / 'tests').glob('*.py'))
    proc = subprocess.run(
        [sys.executable, '-m', 'pyflakes', *files], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
