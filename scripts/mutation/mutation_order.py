# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""pytest plugin of `make mutation`: run each mutant's quickest tests first.

mutmut hands each mutant's covering tests to pytest in no particular order and stops at the
first failure (-x). The tests are sorted by the durations mutmut measured in its statistics run
(mutants/mutmut-stats.json; pytest runs in mutants/), slow-marked ones last, so most mutants
die in the millisecond tests and only survivors pay for the simulations.
"""

import json
from pathlib import Path

import pytest


def _durations() -> dict:
    """Return mutmut's measured duration per test id ({} before its statistics exist)."""
    try:
        return json.loads(Path('mutmut-stats.json').read_text())['duration_by_test']
    except (OSError, ValueError, KeyError):
        return {}


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config, items):
    """Stable sort: quick tests first, by measured duration; slow-marked ones last."""
    durations = _durations()
    items.sort(
        key=lambda item: (
            item.get_closest_marker('slow') is not None,
            durations.get(item.nodeid, 0.0),
        )
    )
