# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The suite's own rules: strict markers, pinned plugins, helpers apart from the test modules."""

from __future__ import annotations

import configparser
import re
from pathlib import Path

TESTS = Path(__file__).resolve().parent
REPO = TESTS.parent
#: The pytest plugins the suite uses (timeout in pytest.ini, flaky in conftest.py, mutmut).
PLUGINS = ('pytest-timeout', 'pytest-rerunfailures', 'mutmut')


def _pins(lock: Path) -> dict[str, str]:
    """Return {normalised name: version} of a lock file."""
    pins = {}
    for line in lock.read_text().splitlines():
        line = line.split('#', 1)[0].strip()
        if line:
            name, version = line.split('==')
            pins[re.sub(r'[-_.]+', '-', name).lower()] = version
    return pins


def test_markers_are_strict() -> None:
    """pytest.ini turns an unregistered marker into an error and registers the suite's four."""
    ini = configparser.ConfigParser()
    ini.read(REPO / 'pytest.ini')
    assert '--strict-markers' in ini['pytest']['addopts'].split()
    names = {m.split(':')[0].strip() for m in ini['pytest']['markers'].strip().splitlines()}
    assert names == {'unit', 'ros', 'realtime', 'slow'}


def test_test_plugins_are_pinned_with_the_test_dependencies() -> None:
    """Each plugin is in python.lock (installed in every mode), not only in colcon.lock."""
    pins = _pins(REPO / 'requirements' / 'python.lock')
    assert all(p in pins for p in PLUGINS), {p: pins.get(p) for p in PLUGINS}
    assert not set(PLUGINS) & set(_pins(REPO / 'requirements' / 'colcon.lock'))


def test_no_test_module_is_a_library_or_skips_at_import() -> None:
    """No module imports a test module (helpers live in *_helpers.py); no import-time skip."""
    for path in sorted(TESTS.glob('*.py')):
        text = path.read_text()
        assert not re.search(r'^\s*(from|import) test_\w+', text, re.M), path.name
        assert not re.search(r'^pytest\.importorskip\(', text, re.M), path.name
