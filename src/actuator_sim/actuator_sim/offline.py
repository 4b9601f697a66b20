# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Offline closed-loop simulation of the paper's cases: ``offline_sim case1 | case2 | run``.

Prints each result next to the paper's number, writes JSON and saves every trace (.npz)
so Figures 5-7 can be drawn (``bag_analyze`` draws them from bags; ``--plot`` here).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np
from tabulate import tabulate

from actuator_controller.laws import CONTROLLER_NAMES
from actuator_controller.ppf import PrescribedPerformance
from actuator_controller.reference import REFERENCE_KINDS
from actuator_core.metrics import STEADY_STATE_START_S, RunMetrics, compute_run_metrics
from actuator_core.status import Status
from actuator_sim.loop import ClosedLoop, Scenario
from actuator_sim.scenarios import CONDITIONS, case1, case2, paper_scenario
from actuator_sim.stability import radius_along_envelope


def trace_metrics(
    trace: dict[str, np.ndarray], steady_state_start_s: float = STEADY_STATE_START_S
) -> RunMetrics:
    """Metrics of a trace; runs without an envelope of their own are judged against Table 4's PPF.

    A sample on which the controller latched its safe stop counts as a non-finite error: the run
    is reported as diverged, never with the numbers it had before the stop.
    """
    t = trace['t_s']
    error = trace['error_rad']
    if 'status' in trace:
        error = np.where(np.asarray(trace['status']) == Status.LATCHED, np.nan, error)
    lower, upper = trace['lower_bound_rad'], trace['upper_bound_rad']
    if not np.all(np.isfinite(lower)):
        lower, upper = PrescribedPerformance().bounds(t)
    return compute_run_metrics(
        t,
        error,
        trace['current_a'],
        lower,
        upper,
        trace['saturated'],
        trace['x2_hat_rad_s'] - trace['true_velocity_rad_s'],
        trace['x3_hat_rad_s2'] - trace['true_disturbance_rad_s2'],
        steady_state_start_s,
    )


def run_scenario(scenario: Scenario) -> tuple[dict[str, np.ndarray], RunMetrics, float, float]:
    """Simulate one scenario: (trace, metrics, worst spectral radius, wall seconds)."""
    start = time.perf_counter()
    trace = ClosedLoop(scenario).run()
    wall = time.perf_counter() - start
    metrics = trace_metrics(trace)
    if len(trace['t_s']) < scenario.samples:
        metrics = dataclasses.replace(metrics, diverged=True)
    radius = max(
        r
        for _, r in radius_along_envelope(
            scenario.controller,
            scenario.gains,
            times_s=(0.0, 5.0, 10.0),
            eso=scenario.eso,
            dt_s=scenario.common.dt_s,
            plant=scenario.plant,
        )
    )
    return trace, metrics, radius, wall


def _fmt(x: float) -> str:
    """Engineering format, or a dash for NaN."""
    return '—' if x is None or (isinstance(x, float) and math.isnan(x)) else f'{x:.3e}'


def verdict(metrics: RunMetrics, radius: float) -> str:
    """Return what the numbers of a run may be taken for."""
    if metrics.diverged:
        return 'DIVERGED: no figure reported'
    if metrics.saturated_fraction > 0.5:
        return (
            f'NOT A RESULT: saturated {metrics.saturated_fraction:.0%} of samples '
            f'(linearised radius {radius:.3g})'
        )
    note = (
        f' (at the current limit in {metrics.saturated_fraction:.0%} of samples)'
        if metrics.saturated_fraction >= 0.01
        else ''
    )
    return (
        'ok' if radius < 1.0 else f'bounded although linearised radius {radius:.3f} >= 1'
    ) + note


def print_table(title: str, rows: list[dict]) -> None:
    """One line per run: the paper's number, ours, their ratio and the other figures (tabulate)."""
    lines = []
    for r in rows:
        m = r['metrics']
        ours = m['max_steady_error_rad']
        no_ratio = m['diverged'] or r['verdict'].startswith('NOT') or math.isnan(r['paper_rad'])
        lines.append(
            (
                r['name'],
                '—' if r['verdict'].startswith(('DIVERGED', 'NOT')) else _fmt(ours),
                _fmt(r['paper_rad']),
                '—' if no_ratio else f'{ours / r["paper_rad"]:.2f}',
                _fmt(m['rms_error_rad']),
                f'{m["max_abs_current_a"]:.2f}',
                str(m['bounds_kept']),
                f'{100 * m["saturated_fraction"]:.1f}',
                f'{r["spectral_radius"]:.4f}',
                r['verdict'],
            )
        )
    print(title)
    print(
        tabulate(
            lines,
            headers=(
                'run',
                'max ss err',
                'paper',
                'ratio',
                'RMS err',
                'max|u| A',
                'PPF kept',
                'sat %',
                'radius',
                'verdict',
            ),
            tablefmt='simple',
            disable_numparse=True,
            colalign=('left',) + ('right',) * 8 + ('left',),
        )
    )


def run_case(runs: list[tuple[Scenario, float]], traces_dir: Path | None) -> list[dict]:
    """Simulate each (scenario, paper value); save traces; return JSON-ready rows."""
    rows = []
    for scenario, paper in runs:
        trace, metrics, radius, wall = run_scenario(scenario)
        if traces_dir is not None:
            traces_dir.mkdir(parents=True, exist_ok=True)
            # numpy's stub types **kwds as if they could hold its allow_pickle flag
            np.savez_compressed(traces_dir / f'{scenario.name}.npz', **trace)  # type: ignore[arg-type]
        rows.append(
            {
                'name': scenario.name,
                'controller': scenario.controller,
                'reference': scenario.reference,
                'pressure_pa': scenario.plant.condition.pressure_pa,
                'temperature_c': scenario.plant.condition.temperature_c,
                'gains': None if scenario.gains is None else dataclasses.asdict(scenario.gains),
                'paper_rad': paper,
                'metrics': metrics.as_dict(),
                'spectral_radius': radius,
                'verdict': verdict(metrics, radius),
                'wall_s': wall,
                'realtime_factor': scenario.duration_s / wall,
            }
        )
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point."""
    parser = argparse.ArgumentParser(
        prog='offline_sim', description='Offline closed-loop simulation of the paper.'
    )
    parser.add_argument(
        'case', choices=('case1', 'case2', 'run'), help='the paper case, or one custom run'
    )
    parser.add_argument(
        '--duration', type=float, default=10.0, help='simulated seconds per run (default 10)'
    )
    parser.add_argument('--json', type=Path, help='write the results as JSON to this file')
    parser.add_argument(
        '--traces',
        type=Path,
        default=Path('results/offline'),
        help='folder for the .npz traces (default results/offline)',
    )
    parser.add_argument('--no-traces', action='store_true', help='do not save traces')
    parser.add_argument(
        '--controller', choices=CONTROLLER_NAMES, default='pp_nftsmc_eso', help='for "run"'
    )
    parser.add_argument('--reference', choices=REFERENCE_KINDS, default='fast', help='for "run"')
    parser.add_argument(
        '--condition', choices=tuple(CONDITIONS), default='deep_sea', help='for "run"'
    )
    args = parser.parse_args(argv)
    if not 0.0 < args.duration <= 3600.0:
        parser.error('--duration must be in (0, 3600] s')
    if args.duration <= STEADY_STATE_START_S:
        parser.error(
            f'--duration must exceed the steady-state window start ({STEADY_STATE_START_S} s)'
        )
    if args.case == 'case1':
        runs, title = (
            case1(args.duration),
            'Case 1 (Table 5): PP-NFTSMC-ESO, max steady-state error',
        )
    elif args.case == 'case2':
        runs, title = (
            case2(args.duration),
            'Case 2 (Table 6): fast trajectory, deep sea (10 MPa, 2 degC)',
        )
    else:
        runs = [
            (
                paper_scenario(
                    f'run_{args.controller}_{args.reference}_{args.condition}',
                    args.controller,
                    args.reference,
                    args.condition,
                    args.duration,
                ),
                float('nan'),
            )
        ]
        title = 'Single run'
    traces = None if args.no_traces else args.traces / args.case
    rows = run_case(runs, traces)
    print_table(
        f'{title}; {args.duration:g} s at 1 ms, steady-state window '
        f'[{STEADY_STATE_START_S:g}, {args.duration:g}] s',
        rows,
    )
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps({'case': args.case, 'runs': rows}, indent=2, default=float)
        )
        print(f'JSON: {args.json}')
    if traces is not None:
        print(f'traces: {traces}/*.npz')
    return 0


if __name__ == '__main__':
    sys.exit(main())
