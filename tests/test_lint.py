# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Static checks as ROS 2 packages run them: ament_flake8/ament_pep257 (ruff) and ament_copyright.

The rules live in the repository's ruff.toml; its extend-exclude list is also the list of files
the header check skips. The type check of src/ is mypy's with the repository's mypy.ini.
"""

import fnmatch
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / 'ruff.toml'
MYPY_CONFIG = ROOT / 'mypy.ini'
CHECKED = ('src', 'tests')
HEADER = ('# Copyright 2026 Actuator control team', '# SPDX-License-Identifier: Apache-2.0')


def ruff(*args):
    """Run the venv's ruff with the repository's configuration, from the repository root."""
    cmd = [sys.executable, '-m', 'ruff', *args, '--config', str(CONFIG), *CHECKED]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)


def excluded(rel):
    """Whether ruff.toml's extend-exclude names the file or one of its folders.

    A pattern with a slash is a glob on the path from the repository root; one without, a glob
    on any single path component (ruff's rules for these patterns).
    """
    patterns = tomllib.loads(CONFIG.read_text())['extend-exclude']
    parts = rel.split('/')
    prefixes = ['/'.join(parts[: i + 1]) for i in range(len(parts))]
    for pattern in patterns:
        pattern = pattern.rstrip('/')
        if '/' in pattern:
            if any(fnmatch.fnmatchcase(p, pattern) for p in prefixes):
                return True
        elif any(fnmatch.fnmatchcase(part, pattern) for part in parts):
            return True
    return False


def python_files():
    """List the .py files under src/ and tests/ that ruff.toml does not exclude (root-relative)."""
    files = set()
    for top in CHECKED:
        for path in (ROOT / top).rglob('*.py'):
            rel = path.relative_to(ROOT).as_posix()
            if not excluded(rel):
                files.add(rel)
    return sorted(files)


def test_ruff_finds_nothing():
    proc = ruff('check', '--no-cache', '--output-format', 'concise')
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_isort_knows_every_project_package():
    """ruff.toml's known-first-party names every src/<pkg>: one import order anywhere."""
    known = tomllib.loads(CONFIG.read_text())['lint']['isort']['known-first-party']
    packages = [p.name for p in (ROOT / 'src').iterdir() if (p / 'package.xml').is_file()]
    assert sorted(known) == sorted(packages)


def package_modules():
    """Count the .py files of every Python package src/<pkg>/<pkg> (what mypy.ini checks)."""
    packages = [
        p / p.name for p in (ROOT / 'src').iterdir() if (p / p.name / '__init__.py').is_file()
    ]
    return sum(1 for package in packages for _ in package.rglob('*.py'))


@pytest.mark.slow
def test_mypy_finds_nothing():
    cmd = [sys.executable, '-m', 'mypy', '--config-file', str(MYPY_CONFIG)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    # mypy.ini's files cover every package: a new one is checked from its first commit
    expected = f'no issues found in {package_modules()} source files'
    assert expected in proc.stdout, proc.stdout


def test_every_python_file_has_the_license_header():
    files = python_files()
    # The same files as ruff checks: the exclusions are read alike.
    proc = ruff('check', '--no-cache', '--show-files')
    assert proc.returncode == 0, proc.stderr
    shown = sorted(Path(line).relative_to(ROOT).as_posix() for line in proc.stdout.splitlines())
    assert files == shown
    missing = []
    for rel in files:
        lines = (ROOT / rel).read_text().splitlines()
        if lines and lines[0].startswith('#!'):
            lines = lines[1:]
        if tuple(lines[: len(HEADER)]) != HEADER:
            missing.append(rel)
    assert not missing, 'no license header (' + ' / '.join(HEADER) + ') in: ' + ', '.join(missing)
