# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Targets, rows and the printed table of the benchmark (``bench``): medians, spreads, verdicts."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
from tabulate import tabulate

from actuator_bench.bench_figures import NODES, START_UP_S, Figures

# --- aggregation and targets ---------------------------------------------------------------------


@dataclass(frozen=True)
class Target:
    """An inclusive band [low, high] a figure should lie in, with its text for the table."""

    text: str
    low: float = -math.inf
    high: float = math.inf

    def met(self, value: Optional[float]) -> Optional[bool]:
        """True/False, or None when there is no finite value."""
        if value is None or not math.isfinite(value):
            return None
        return self.low <= value <= self.high


@dataclass(frozen=True)
class Spread:
    """Median, min and max of a figure over repeats (runs without the figure left out)."""

    median: Optional[float]
    low: Optional[float]
    high: Optional[float]
    n: int


def spread(values: Sequence[Optional[float]]) -> Spread:
    """Median/min/max of the finite values."""
    finite = [v for v in values if v is not None and math.isfinite(v)]
    if not finite:
        return Spread(None, None, None, 0)
    return Spread(float(np.median(finite)), float(min(finite)), float(max(finite)), len(finite))


def verdict(target: Optional[Target], values: Sequence[Optional[float]]) -> str:
    """'PASS k/n' or 'MISS k/n' by the median (k runs met the target), '' without a target.

    'n/a' without data.
    """
    if target is None:
        return ''
    met = [target.met(v) for v in values]
    judged = [m for m in met if m is not None]
    median_met = target.met(spread(values).median)
    if median_met is None:
        return 'n/a'
    return f'{"PASS" if median_met else "MISS"} {sum(judged)}/{len(judged)}'


@dataclass(frozen=True)
class Row:
    """One line of the table: figure key, label, unit, number format and target (if any)."""

    key: str
    label: str
    unit: str
    fmt: str = '.1f'
    target: Optional[Target] = None


def realtime_rows(period_us: float) -> list[Row]:
    """Table lines of a real-time variant, with the issue's targets."""
    tol = period_us * 1e-3
    ratio = Target('0.8 - 1.2', 0.8, 1.2)
    rows = [
        Row('safe_stop', 'controller latched safe stop (1 = yes)', 'flag', '.6g'),
        Row('controlled_span_s', 'controller timing log span (to latch)', 's'),
        Row('controlled_pct', 'plant samples the log answers', '%', '.2f'),
        Row(
            'period_mean_us',
            'tick period mean',
            'us',
            '.2f',
            Target(f'{period_us:g} +- {tol:g}', period_us - tol, period_us + tol),
        ),
        Row('period_p50_us', 'tick period p50', 'us'),
        Row('period_p99_us', 'tick period p99', 'us'),
        Row('period_max_us', 'tick period max', 'us'),
        Row(
            'period_max_after_start_us',
            f'tick period max after the first {START_UP_S:g} s',
            'us',
        ),
        Row(
            'period_dev_p99_us',
            f'tick |period - {period_us:g} us| p99',
            'us',
            '.1f',
            Target('<= 100', high=100.0),
        ),
        Row(
            'periods_over_2x',
            f'ticks > {2 * period_us:g} us',
            'count',
            '.6g',
            Target('0', high=0.0),
        ),
        Row('missed_samples', 'missed samples (stamp gaps)', 'count', '.6g'),
        Row('latency_p50_us', 'sensor-to-command latency p50', 'us'),
        Row(
            'latency_p99_us',
            'sensor-to-command latency p99',
            'us',
            '.1f',
            Target('<= 300', high=300.0),
        ),
        Row('latency_max_us', 'sensor-to-command latency max', 'us'),
        Row('latency_over_period', f'commands > {period_us:g} us after stamp', 'count', '.6g'),
        Row('plant_late_p50_us', '  part: plant tick late p50', 'us'),
        Row('plant_late_p99_us', '  part: plant tick late p99', 'us'),
        Row('transport_p99_us', '  part: plant->controller p99', 'us'),
        Row('controller_wait_p99_us', '  part: controller wait+compute p99', 'us'),
        Row('compute_p50_us', 'control compute p50', 'us'),
        Row('compute_p99_us', 'control compute p99', 'us'),
        Row('held_same_pct', 'command reaches plant: same sample', '%', '.2f'),
        Row('held_next_pct', 'command reaches plant: next sample', '%', '.2f'),
        Row('held_later_pct', 'command reaches plant: later', '%', '.2f'),
        Row('held_none_pct', 'plant held no command', '%', '.2f'),
        Row('held_in_time_pct', 'same or next sample', '%', '.2f', Target('100', low=100.0)),
    ]
    return (
        rows
        + eso_rows()
        + error_rows(ratio)
        + [
            Row('steady_gap_max_ms', '  plant: longest gap in the steady window', 'ms'),
            Row(
                'steady_gaps_beyond_timeout',
                '  ... gaps beyond the measurement timeout',
                'count',
                '.6g',
            ),
            Row(
                'observer_input_differing',
                '  ESO input current not the one the joint held',
                'samples',
                '.6g',
            ),
        ]
        + node_rows(Target('<= 25', high=25.0), Target('<= 80', high=80.0))
        + [
            Row('fifo_nodes', 'nodes granted SCHED_FIFO', 'count', '.6g'),
            Row('plant_interval_max_us', 'longest gap between plant samples', 'us'),
            Row('steal_pct', 'CPU steal by the hypervisor', '%', '.2f'),
            Row('wall_s', 'wall time of the run', 's'),
        ]
    )


def sim_rows(period_us: float) -> list[Row]:
    """Table lines of the sim-time variant (speed target; the rest for reference)."""
    return (
        [
            Row('safe_stop', 'controller latched safe stop (1 = yes)', 'flag', '.6g'),
            Row(
                'speed_x',
                'speed: sim s / wall s (plant span)',
                'x',
                '.3f',
                Target('>= 3', low=3.0),
            ),
            Row('plant_interval_p50_us', 'wall per sample p50', 'us'),
            Row('plant_interval_p99_us', 'wall per sample p99', 'us'),
            Row('compute_p50_us', 'control compute p50', 'us'),
            Row('compute_p99_us', 'control compute p99', 'us'),
            Row('held_same_pct', 'command reaches plant: same sample', '%', '.2f'),
            Row('held_in_time_pct', 'same or next sample', '%', '.2f', Target('100', low=100.0)),
        ]
        + eso_rows()
        + error_rows(None)
        + node_rows(None, None)
        + [Row('wall_s', 'wall time of the run', 's')]
    )


def eso_rows() -> list[Row]:
    """ESO pairing lines (exactly the commanded current each sample)."""
    return [
        Row('eso_exact_pct', 'ESO steps with the exact command', '%', '.3f'),
        Row(
            'eso_exact_or_repaired_pct',
            '  ... on time or repaired when late',
            '%',
            '.3f',
            Target('100', low=100.0),
        ),
        Row('eso_substituted', 'ESO substituted pairs', 'count', '.6g'),
        Row('eso_repaired', '  ... repaired when the command came', 'count', '.6g'),
        Row('eso_refused', 'ESO refused inputs', 'count', '.6g', Target('0', high=0.0)),
    ]


def error_rows(ratio: Optional[Target]) -> list[Row]:
    """Tracking error lines; with ``ratio`` also the ratios to the sim-time reference."""
    rows = [Row('max_steady_error_rad', 'max steady-state error', 'rad', '.3e')]
    if ratio is not None:
        rows.append(Row('error_ratio_max_steady', '  / sim-time run', 'ratio', '.3f', ratio))
    rows.append(Row('rms_error_rad', 'RMS error', 'rad', '.3e'))
    if ratio is not None:
        rows.append(Row('error_ratio_rms', '  / sim-time run', 'ratio', '.3f', ratio))
    return rows + [Row('diverged', 'diverged (1 = yes)', 'flag', '.6g')]


def node_rows(cpu: Optional[Target], rss: Optional[Target]) -> list[Row]:
    """CPU and peak RSS per node."""
    loop = Row(
        'cpu_joint_loop_pct',
        'CPU joint + ESO + controller',
        '% core',
        '.1f',
        Target('<= 50', high=50.0),
    )

    # Per-node targets are for one node's process; a composed loop's process holds three nodes
    # and is judged by the row above.
    def per_node(target: Optional[Target], node: str) -> Optional[Target]:
        return None if node == 'loop' else target

    return (
        [loop]
        + [Row(f'cpu_{n}_pct', f'CPU {n}', '% core', '.1f', per_node(cpu, n)) for n in NODES]
        + [Row(f'rss_{n}_mb', f'peak RSS {n}', 'MB', '.1f', per_node(rss, n)) for n in NODES]
    )


def floor_rows() -> list[Row]:
    """Floor lines: one hop, an echo's CPU (floor.py); a lone grid thread's stalls (host)."""
    return [
        Row('floor_hop_p50_us', 'one hop (round trip / 2) p50', 'us'),
        Row('floor_hop_p99_us', 'one hop p99', 'us'),
        Row('floor_hop_max_us', 'one hop max', 'us'),
        Row('floor_lost_pct', 'messages not echoed', '%', '.3f'),
        Row('cpu_echo_pct', 'CPU echo (1 sub + 1 pub per sample)', '% core'),
        Row('cpu_source_pct', 'CPU source (1 pub + 1 sub per sample)', '% core'),
        Row('steal_pct', 'CPU steal by the hypervisor', '%', '.2f'),
    ] + [
        row
        for label, where in (('host_cpu0', 'on CPU 0'), ('host_any', 'on any CPU'))
        for row in (
            Row(f'{label}_stalls_per_min', f'host: grid thread {where} woke > 2 ms late', '/min'),
            Row(f'{label}_beyond_timeout_per_min', '  ... beyond the measurement timeout', '/min'),
            Row(f'{label}_stall_max_ms', '  ... the longest stall', 'ms'),
        )
    ]


def offline_rows(batches: Sequence[int]) -> list[Row]:
    """Offline speed lines."""
    return [Row('offline_scalar_x', 'scalar ClosedLoop', 'sim s/wall s', '.2f')] + [
        Row(f'offline_batch_{n}_x', f'ClosedLoop batch={n} (total)', 'sim s/wall s', '.2f')
        for n in batches
    ]


# --- table ---------------------------------------------------------------------------------------


def cell(value: Optional[float], fmt: str) -> str:
    """Return a number in ``fmt``, or 'n/a'."""
    return 'n/a' if value is None or not math.isfinite(value) else format(value, fmt)


def format_table(sections: Sequence[tuple[str, list[Row], list[Figures]]]) -> str:
    """Return the table (tabulate).

    Per section (title, rows, per-run figures) one line per figure present in any run.
    """
    lines = []
    for title, rows, runs in sections:
        lines.append(
            (f'{title} ({len(runs)} run{"s" if len(runs) != 1 else ""})', '', '', '', '', '', '')
        )
        for row in rows:
            values = [r.get(row.key) for r in runs]
            if all(v is None for v in values) and row.target is None:
                continue
            s = spread(values)
            lines.append(
                (
                    f'  {row.label}',
                    row.unit,
                    cell(s.median, row.fmt),
                    cell(s.low, row.fmt),
                    cell(s.high, row.fmt),
                    row.target.text if row.target else '',
                    verdict(row.target, values),
                )
            )
    return tabulate(
        lines,
        headers=('figure', 'unit', 'median', 'min', 'max', 'target', 'verdict'),
        tablefmt='simple',
        disable_numparse=True,
        colalign=('left', 'right', 'right', 'right', 'right', 'left', 'left'),
    )


def section_summary(rows: list[Row], runs: list[Figures]) -> dict:
    """JSON form of a section: per figure median/min/max/n, target and verdict."""
    out = {}
    for row in rows:
        values = [r.get(row.key) for r in runs]
        s = spread(values)
        out[row.key] = {
            'unit': row.unit,
            'median': s.median,
            'min': s.low,
            'max': s.high,
            'n': s.n,
            'target': row.target.text if row.target else None,
            'verdict': verdict(row.target, values),
        }
    return out
