# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The closed-loop description (actuator_tools.graph) and the runner's options that shape it."""

from __future__ import annotations

import pytest

from actuator_tools import bringup
from actuator_tools.graph import LIVE_DIAGNOSTICS_RATE_HZ, closed_loop


def _rates(specs) -> dict:
    """Return {key: rate} of controller/state and plant/truth in ``specs``."""
    by_key = {s.key: s.parameters for s in specs}
    return {
        'state': by_key['controller']['state_rate_hz'],
        'truth': by_key['plant']['truth_rate_hz'],
    }


@pytest.mark.parametrize(
    'mode, record, expected',
    [
        ('realtime', True, 0.0),  # the bag analysis needs every sample
        ('sim', False, 0.0),  # the paper's analysis: every sample
        ('realtime', False, LIVE_DIAGNOSTICS_RATE_HZ),  # live use only
    ],
)
def test_diagnostic_topics_default_to_every_sample_unless_nothing_records(mode, record, expected):
    """controller/state and plant/truth: every sample when recorded or in sim, else decimated."""
    assert _rates(closed_loop(mode, 5.0, record=record)) == {'state': expected, 'truth': expected}


@pytest.mark.parametrize('mode, record', [('realtime', True), ('realtime', False), ('sim', True)])
def test_a_diagnostics_rate_the_user_sets_reaches_both_topics(mode, record):
    """diagnostics_rate_hz overrides the default for the controller and the plant alike."""
    specs = closed_loop(mode, 5.0, record=record, diagnostics_rate_hz=250.0)
    assert _rates(specs) == {'state': 250.0, 'truth': 250.0}
    assert _rates(closed_loop(mode, 5.0, record=record, diagnostics_rate_hz=0.0)) == {
        'state': 0.0,
        'truth': 0.0,
    }


@pytest.mark.parametrize('rate', ['-1', '20000', 'nan'])
def test_bringup_refuses_a_diagnostics_rate_out_of_range_in_one_line(rate, capsys):
    """A rate outside limits.DIAGNOSTICS_RATE_RANGE_HZ: argparse's one-line error, exit 2."""
    with pytest.raises(SystemExit) as stop:
        bringup.main(['--diagnostics-rate', rate, '--duration', '1'])
    assert stop.value.code == 2
    assert '--diagnostics-rate must be in [0, 10000] Hz' in capsys.readouterr().err
