# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The offline paper cases reproduce their golden figures to the printed digit and bit.

Pinned in tests/golden/offline.json (tests/golden_offline.py writes it on purpose); a change
fails with the stored and the new figure side by side and the command that regenerates them.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import golden_offline
from actuator_controller.laws import PpNftsmcGains
from actuator_sim.offline import run_scenario
from actuator_sim.scenarios import paper_scenario


@pytest.mark.slow
@pytest.mark.parametrize('case', sorted(golden_offline.CASES))
def test_case_reproduces_its_golden_figures(case: str) -> None:
    """Every printed figure of each run and the case's trace checksum equal the stored ones."""
    stored = golden_offline.load_golden()[case]
    now = golden_offline.compute_case(case)
    rows = golden_offline.differences(stored, now)
    assert not rows, golden_offline.report(case, rows)


@pytest.mark.slow
@pytest.mark.parametrize('case', sorted(golden_offline.CASES))
def test_first_second_of_each_run_reproduces_its_checksum(case: str) -> None:
    """Quick set: the first second of every run of the case, bit for bit as stored."""
    stored = golden_offline.load_golden()[case]['short_trace_sha256']
    now = golden_offline.short_checksum(case)
    rows = [] if now == stored else [('short_trace_sha256', stored[:16], now[:16])]
    assert not rows, golden_offline.report(case, rows)


def test_golden_file_covers_every_run_and_figure() -> None:
    """The file pins all four Case 1 runs and all five Case 2 runs, each with every figure."""
    stored = golden_offline.load_golden()
    assert sorted(stored['case1']['runs']) == sorted(
        f'case1_{r}_{c}' for r in ('slow', 'fast') for c in ('lab', 'deep_sea')
    )
    assert sorted(stored['case2']['runs']) == sorted(
        f'case2_{c}' for c in ('pi', 'smc_eso_printed', 'smc_eso', 'nftsmc_eso', 'pp_nftsmc_eso')
    )
    fields = {'max_steady_error_rad', 'rms_error_rad', 'max_abs_current_a', 'spectral_radius'}
    for case in stored.values():
        assert len(case['trace_sha256']) == len(case['short_trace_sha256']) == 64
        for figures in case['runs'].values():
            assert fields <= set(figures)


@pytest.mark.slow
def test_a_ten_percent_gain_change_is_caught() -> None:
    """k0 of PP-NFTSMC-ESO +10 % (100 -> 110 1/s): the hardest run's figures differ."""
    stored = golden_offline.load_golden()['case2']['runs']['case2_pp_nftsmc_eso']
    base = PpNftsmcGains()
    gains = dataclasses.replace(base, k0_per_s=base.k0_per_s * 1.1)
    scenario = paper_scenario('case2_pp', 'pp_nftsmc_eso', 'fast', 'deep_sea', 10.0, gains)
    trace, metrics, radius, _ = run_scenario(scenario)
    changed = golden_offline.printed_figures(metrics, radius)
    assert changed['max_steady_error_rad'] != stored['max_steady_error_rad']
    assert changed['rms_error_rad'] != stored['rms_error_rad']
    assert np.all(np.isfinite(trace['error_rad']))


def test_checksum_sees_one_bit() -> None:
    """The checksum differs when one value of one field moves by one unit in the last place."""
    trace = {'run': {'a': np.array([1.0, 2.0]), 'b': np.array([3.0])}}
    moved = {'run': {'a': np.array([1.0, np.nextafter(2.0, 3.0)]), 'b': np.array([3.0])}}
    assert golden_offline.trace_checksum(trace) != golden_offline.trace_checksum(moved)
    assert golden_offline.trace_checksum(trace) == golden_offline.trace_checksum(
        {'run': {'b': np.array([3.0]), 'a': np.array([1.0, 2.0])}}
    )


def test_report_puts_old_and_new_side_by_side() -> None:
    """A difference names the figure, the stored and the new value and the regenerate command."""
    old = {'runs': {'r': {'rms_error_rad': '1.000e-04'}}, 'trace_sha256': 'a' * 64}
    new = {'runs': {'r': {'rms_error_rad': '1.100e-04'}}, 'trace_sha256': 'b' * 64}
    rows = golden_offline.differences(old, new)
    assert rows == [
        ('r.rms_error_rad', '1.000e-04', '1.100e-04'),
        ('trace_sha256', 'a' * 16, 'b' * 16),
    ]
    text = golden_offline.report('caseX', rows)
    assert 'r.rms_error_rad  1.000e-04 -> 1.100e-04' in text
    assert golden_offline.REGENERATE in text
    assert golden_offline.differences(old, old) == []
