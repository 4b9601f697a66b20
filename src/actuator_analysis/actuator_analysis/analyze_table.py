# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The text table of ``bag_analyze``: a row per figure, a column per bag (see ``analyze``)."""

from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np
from tabulate import tabulate

from actuator_core.status import Status

from .analyze import RunReport, observer_input, steady_empty
from .mismatch import START_S, WINDOW_S, WORTH_IDENTIFYING


def _steady(r: RunReport, value: Optional[float], unit: str) -> str:
    """Format a steady-window figure, or say why there is none."""
    if steady_empty(r.metrics):
        return 'n/a (run shorter than the steady window)'
    return _num(value, unit)


def _window(r: RunReport) -> str:
    """Format the steady window, or say that the run ends before it starts."""
    start, end = r.metrics.steady_window_s
    if end < start:
        return f'none: the run lasts {end:.3f} s, the window starts at {start:g} s'
    return f'{start:.1f}-{end:.3f} s'


def _latency(r: RunReport) -> str:
    """Format the recorder delay, or say why a bag has none."""
    if r.timing['command_latency']:
        return _timing(r.timing['command_latency'])
    run = r.run
    if run.log_clock == 'sim':
        return 'n/a (logged on sim time)'
    if run.log_clock == 'wall' and run.stamp_clock == 'sim':
        return 'n/a (sim-time stamps, wall-clock log)'
    return 'n/a'


def _diagnostics(r: RunReport) -> str:
    """``name: worst (reports per level)`` per component, or n/a."""
    if not r.run.diagnostics:
        return 'n/a (not recorded)'
    parts = []
    for name, d in sorted(r.run.diagnostics.items()):
        if d['worst'] is None:  # nothing to judge the run by: never OK
            outside = sum(d['before_run'].values()) + sum(d['after_run'].values())
            parts.append(f'{name} none stamped inside the run ({outside} outside it)')
            continue
        levels = ' '.join(f'{k} {v}' for k, v in d['levels'].items())
        why = f': {d["reasons"][0]}' if d['reasons'] else ''
        parts.append(f'{name} {d["worst"]} ({levels}){why}')
    return '\n'.join(parts)


def _observer_input(r: RunReport) -> str:
    """``k of n samples differ, max x A``, or n/a without the truth."""
    figures = observer_input(r.run)
    if figures is None:
        return 'n/a (no truth)'
    return (
        f'{figures["differing"]} of {figures["samples"]} samples differ, '
        f'max {figures["max_abs_a"]:.3g} A'
    )


def _b0(r: RunReport) -> str:
    """Format the joint's theta1 as the run shows it against the observer's theta1n."""
    b = r.b0
    if b is None:
        return f'n/a (no {WINDOW_S:g} s window of control after {START_S:g} s)'
    seen = f'{b.theta1_seen:.4g} rad/s^2/A'
    theta1n, relative = b.theta1n, b.relative
    if not theta1n or relative is None:  # (the one condition: relative needs theta1n)
        return f'joint {seen} (theta1n not recorded: no eso/estimate)'
    low, high = (100 * (x / theta1n - 1) for x in (b.window_low, b.window_high))
    text = (
        f'joint {seen}, {100 * relative:+.1f} % from theta1n {theta1n:.4g} '
        f'({b.windows} windows of {WINDOW_S:g} s: {low:+.1f} to {high:+.1f} %)'
    )
    if high - low > 2 * 100 * WORTH_IDENTIFYING:
        return text + ": the joint's theta1 drifts"
    if abs(relative) > WORTH_IDENTIFYING:
        return text + ': identify the joint (bag_identify)'
    return text


def _against_truth(errors: Optional[np.ndarray], value: Optional[float], unit: str) -> str:
    """Format an estimation figure, or n/a when the bag has no plant/truth to pair with."""
    return 'n/a (no truth)' if errors is None else _num(value, unit)


def _num(value: Optional[float], unit: str, fmt: str = '.3e') -> str:
    """Format a number with its unit, or n/a."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return 'n/a'
    return f'{value:{fmt}} {unit}'


def _timing(stats: Optional[dict[str, float]]) -> str:
    """p50/p99/max in ms, or n/a."""
    if not stats:
        return 'n/a'
    return '{:.3f}/{:.3f}/{:.3f} ms'.format(
        stats['p50_s'] * 1e3, stats['p99_s'] * 1e3, stats['max_s'] * 1e3
    )


def format_table(reports: Sequence[RunReport]) -> str:
    """Format a text table: one row per figure, one column per bag."""
    rows: list[tuple[str, list[str]]] = []

    def add(label: str, cells: list[str]) -> None:
        rows.append((label, cells))

    add('bag', [r.run.name for r in reports])
    add('controller', [r.run.controller for r in reports])
    add(
        'samples / duration',
        [f'{r.metrics.samples} / {r.metrics.duration_s:.3f} s' for r in reports],
    )
    add('diverged', ['YES' if r.metrics.diverged else 'no' for r in reports])
    add(
        'status not OK',
        [f'{100 * np.mean(r.run.status != Status.OK):.2f} % of samples' for r in reports],
    )
    add('clock (stamps)', [r.run.stamp_clock for r in reports])
    add('steady window', [_window(r) for r in reports])
    add(
        'max |e| in steady window',
        [_steady(r, r.metrics.max_steady_error_rad, 'rad') for r in reports],
    )
    add(
        'RMS e in steady window',
        [_steady(r, r.metrics.rms_steady_error_rad, 'rad') for r in reports],
    )
    add('RMS e whole run', [_num(r.metrics.rms_error_rad, 'rad') for r in reports])
    add('max |u|', [_num(r.metrics.max_abs_current_a, 'A', '.4f') for r in reports])
    add('RMS u', [_num(r.metrics.rms_current_a, 'A', '.4f') for r in reports])
    add('saturated', [f'{100 * r.metrics.saturated_fraction:.2f} %' for r in reports])
    add(
        'PPF bounds',
        [
            (
                'kept'
                if r.metrics.bounds_kept
                else f'VIOLATED at {r.metrics.bounds_violations} samples'
            )
            if r.run.has_envelope
            else 'n/a (no envelope)'
            for r in reports
        ],
    )
    add(
        'RMS velocity est. error',
        [
            _against_truth(
                r.run.velocity_error, r.metrics.rms_velocity_estimate_error_rad_s, 'rad/s'
            )
            for r in reports
        ],
    )
    add(
        'RMS disturbance est. error',
        [
            _against_truth(
                r.run.disturbance_error, r.metrics.rms_disturbance_estimate_error_rad_s2, 'rad/s^2'
            )
            for r in reports
        ],
    )
    add('observer input vs current held', [_observer_input(r) for r in reports])
    add("b0 = theta1n vs the joint's theta1", [_b0(r) for r in reports])
    add('sample period p50/p99/max', [_timing(r.timing['sample_period']) for r in reports])
    add(
        'missed samples',
        [str(r.missed_samples) if r.timing['sample_period'] else 'n/a' for r in reports],
    )
    # The recorder's receive time minus the stamp: the recorder's own delay (it runs at normal
    # scheduling), not the loop's latency, which the controller measures (timing log).
    add('recorder delay (log - stamp) p50/p99/max', [_latency(r) for r in reports])
    add('/diagnostics during the run (worst level)', [_diagnostics(r) for r in reports])
    (_, names), body = rows[0], rows[1:]
    return tabulate(
        [(label, *cells) for label, cells in body],
        headers=('bag', *names),
        tablefmt='simple',
        disable_numparse=True,
    )
