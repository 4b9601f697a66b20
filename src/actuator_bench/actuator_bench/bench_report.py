# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Report of the benchmark (``bench``): the tracking reference, progress lines and the summary.

The real-time runs' tracking error is set against the sim-time runs' (or the offline core's when
there were none); the table is printed and summary.json, runs.csv and table.txt are written.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Sequence

from actuator_bench.bench_figures import Figures, error_ratios
from actuator_bench.bench_run import RunRecord, environment, write_csv
from actuator_bench.bench_table import (
    cell,
    floor_rows,
    format_table,
    offline_rows,
    realtime_rows,
    section_summary,
    sim_rows,
    spread,
)
from actuator_bench.bench_variants import Variant


# --- tracking reference --------------------------------------------------------------------------


def offline_reference(scenario_name: str, duration_s: float) -> Figures:
    """Tracking error of the offline core when no sim-time run was made.

    It is identical to a sim-time run.
    """
    from actuator_sim.loop import ClosedLoop
    from actuator_sim.offline import trace_metrics
    from actuator_sim.params_yaml import all_scenarios

    scenario = dataclasses.replace(all_scenarios()[scenario_name], duration_s=duration_s)
    metrics = trace_metrics(ClosedLoop(scenario).run())
    return {
        'max_steady_error_rad': metrics.max_steady_error_rad,
        'rms_error_rad': metrics.rms_error_rad,
    }


def apply_reference(records: list[RunRecord], reference: Figures) -> None:
    """Add the tracking-error ratios to the sim-time reference to every real-time run."""
    for record in records:
        if not record.variant.startswith('sim'):
            record.figures.update(error_ratios(record.figures, reference))


def tracking_reference(
    records: list[RunRecord], scenario: str, duration_s: float
) -> tuple[Figures, str]:
    """Median error of the sim-time runs, or the offline core's when there were none."""
    sims = [
        r.figures
        for r in records
        if r.variant.startswith('sim') and r.figures.get('max_steady_error_rad') is not None
    ]
    if sims:
        return (
            {
                key: spread([s.get(key) for s in sims]).median
                for key in ('max_steady_error_rad', 'rms_error_rad')
            },
            f'median of {len(sims)} sim-time run(s)',
        )
    return offline_reference(
        scenario, duration_s
    ), 'offline core (ClosedLoop), no sim-time run made'


# --- output --------------------------------------------------------------------------------------


def one_line(record: RunRecord) -> str:
    """Short progress summary of a finished run."""
    if record.error and not record.figures:
        return f'FAILED: {record.error}'
    f = record.figures
    parts = [f'wall {cell(f.get("wall_s"), ".0f")} s']
    if record.variant.startswith('sim'):
        parts.append(f'speed {cell(f.get("speed_x"), ".2f")}x')
    if f.get('latency_p99_us') is not None:
        parts.append(
            f'period dev p99 {cell(f.get("period_dev_p99_us"), ".0f")} us, '
            f'latency p99 {cell(f.get("latency_p99_us"), ".0f")} us'
        )
    parts.append(f'max ss error {cell(f.get("max_steady_error_rad"), ".3e")} rad')
    return ', '.join(parts) + (f' ({record.error})' if record.error else '')


def report(
    args: argparse.Namespace,
    variants: list[Variant],
    records: list[RunRecord],
    offline: list[Figures],
    base: Path,
    period_ns: int,
    env_start: dict,
    interrupted: bool,
    floor: Sequence[Figures] = (),
    floor_priority: int = 0,
) -> int:
    """Print the table and write summary.json, runs.csv and table.txt; return the exit code."""
    has_realtime = any(v.mode == 'realtime' for v in variants)
    reference, reference_source = (
        tracking_reference(records, args.scenario, args.duration)
        if has_realtime and records
        else ({}, 'none')
    )
    apply_reference(records, reference)
    period_us = period_ns / 1e3
    sections = []
    for variant in variants:
        runs = [r.figures for r in records if r.variant == variant.slug and r.figures]
        rows = sim_rows(period_us) if variant.mode == 'sim' else realtime_rows(period_us)
        sections.append((variant.title, rows, runs, variant.slug))
    if floor:
        sched = f'SCHED_FIFO {floor_priority}' if floor_priority else 'normal scheduling'
        sections.append(
            (
                'middleware floor: one message per sample echoed between two processes, '
                f'no control code, {sched}',
                floor_rows(),
                list(floor),
                'floor',
            )
        )
    if offline:
        sections.append(
            (
                f'offline core speed ({args.offline_sim_s:g} simulated s, steps without trace)',
                offline_rows(args.batches),
                offline,
                'offline',
            )
        )
    table = format_table([(title, rows, runs) for title, rows, runs, _ in sections])
    title = (
        f'bench: {args.scenario}, {args.duration:g} s per ROS run, {args.repeats} repeat(s), '
        'medians [min, max]; '
        f'tracking reference: {reference_source}'
    )
    print(f'\n{title}\n{table}')
    failed = [r for r in records if r.error]
    for r in failed:
        print(f'bench: {r.variant} repeat {r.repeat}: {r.error}', file=sys.stderr)
    summary = {
        'config': {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        'period_ns': period_ns,
        'environment_start': env_start,
        'environment_end': environment(),
        'interrupted': interrupted,
        'tracking_reference': {'source': reference_source, **reference},
        'sections': {
            slug: {'title': t, 'figures': section_summary(rows, runs)}
            for t, rows, runs, slug in sections
        },
        'runs': [dataclasses.asdict(r) for r in records],
        'offline_runs': offline,
        'floor_runs': list(floor),
    }
    (base / 'summary.json').write_text(json.dumps(summary, indent=1))
    write_csv(base / 'runs.csv', records, offline)
    (base / 'table.txt').write_text(f'{title}\n{table}\n')
    print(
        f'\nsummary: {base / "summary.json"}; per-run figures: {base / "runs.csv"}; raw files: '
        f'{base}/runs, {base}/bags'
    )
    if interrupted:
        return 130
    return 1 if failed else 0
