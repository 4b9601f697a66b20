# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Performance benchmark of the closed loop (``make bench``): timing, latency, CPU, memory, speed.

Runs plant, ESO, controller and the recorder as separate processes (``bringup.run_closed_loop``)
in real time (normal scheduling and/or SCHED_FIFO) and in deterministic sim time, each
``--repeats`` times, plus the offline core's speed (scalar and batched ``ClosedLoop``). Every
figure is printed as the median over repeats with its min/max spread, next to the issue's
target and PASS/MISS; nothing is asserted. Raw per-run files, summary.json and runs.csv are
kept under ``--out/<UTC timestamp>/``. See benchmarks/README.md for each figure's formula.

The ROS domain is the caller's environment (ROS_DOMAIN_ID); this module never changes it.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime as dt
import json
import math
import os
import platform
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Optional, Sequence

import numpy as np
import psutil
from tabulate import tabulate

from actuator_core.stats import missed_samples, percentiles
from actuator_tools.supervisor import process_log

DEFAULT_SCENARIO = 'case2_pp_nftsmc_eso'
NODES = ('plant', 'eso', 'controller', 'recorder')
RT_VARIANTS = ('normal', 'fifo', 'pinned', 'fifo-pinned', 'fifo-launch')
DURATION_RANGE_S = (1.0, 3600.0)
PROGRESS_EVERY_S = 15.0

Figures = dict[str, Optional[float]]


# --- figures of one run (pure functions of the logged arrays) -----------------------------------


def _percentiles_us(values_ns: np.ndarray, prefix: str) -> Figures:
    """p50, p99 and max of a nanosecond array, in microseconds, keyed ``<prefix>_p50_us`` etc."""
    return {
        f'{prefix}_{k.rsplit("_", 1)[1]}_us': v
        for k, v in percentiles(np.asarray(values_ns, dtype=float) / 1e3, prefix).items()
    }


def period_figures(received_wall_ns: np.ndarray, period_ns: int) -> Figures:
    """Summarise the controller tick periods (diff of arrival wall times).

    mean, p50/p99/max, p99 |deviation|, count > 2 periods.
    """
    periods_ns = np.diff(np.asarray(received_wall_ns, dtype=np.int64))
    figures = _percentiles_us(periods_ns, 'period')
    if periods_ns.size == 0:
        figures.update(period_mean_us=None, period_dev_p99_us=None, periods_over_2x=None)
        return figures
    figures['period_mean_us'] = float(periods_ns.mean() / 1e3)
    figures['period_dev_p99_us'] = float(np.percentile(np.abs(periods_ns - period_ns), 99) / 1e3)
    figures['periods_over_2x'] = float(np.count_nonzero(periods_ns > 2 * period_ns))
    return figures


def latency_figures(latency_ns: np.ndarray, period_ns: int) -> Figures:
    """Sensor-to-command latency (command wall time minus measurement stamp).

    p50/p99/max and count > 1 period.
    """
    latency_ns = np.asarray(latency_ns, dtype=np.int64)
    figures = _percentiles_us(latency_ns, 'latency')
    figures['latency_over_period'] = (
        float(np.count_nonzero(latency_ns > period_ns)) if latency_ns.size else None
    )
    return figures


def latency_breakdown(
    plant_stamp_ns: np.ndarray,
    published_wall_ns: np.ndarray,
    ctrl_stamp_ns: np.ndarray,
    received_wall_ns: np.ndarray,
    latency_ns: np.ndarray,
) -> Figures:
    """Split the latency per sample (joined by stamp).

    Plant timer lateness, transport, controller wait + compute.
    """
    plant_stamp_ns, keep = np.unique(np.asarray(plant_stamp_ns, dtype=np.int64), return_index=True)
    published = np.asarray(published_wall_ns, dtype=np.int64)[keep]
    _, p_idx, c_idx = np.intersect1d(
        plant_stamp_ns, np.asarray(ctrl_stamp_ns, dtype=np.int64), return_indices=True
    )
    stamp = plant_stamp_ns[p_idx]
    published = published[p_idx]
    received = np.asarray(received_wall_ns, dtype=np.int64)[c_idx]
    command = stamp + np.asarray(latency_ns, dtype=np.int64)[c_idx]
    figures: Figures = {}
    for prefix, part in (
        ('plant_late', published - stamp),
        ('transport', received - published),
        ('controller_wait', command - received),
    ):
        stats = _percentiles_us(part, prefix)
        figures[f'{prefix}_p50_us'], figures[f'{prefix}_p99_us'] = (
            stats[f'{prefix}_p50_us'],
            stats[f'{prefix}_p99_us'],
        )
    return figures


def held_command_fractions(
    stamp_ns: np.ndarray, held_command_stamp_ns: np.ndarray, period_ns: int
) -> Figures:
    """Per plant sample after the first, % whose held command answered the previous sample (same).

    The one before (next), older, none.
    """
    stamp = np.asarray(stamp_ns, dtype=np.int64)[1:]
    held = np.asarray(held_command_stamp_ns, dtype=np.int64)[1:]
    keys = (
        'held_same_pct',
        'held_next_pct',
        'held_later_pct',
        'held_none_pct',
        'held_odd_pct',
        'held_in_time_pct',
    )
    if stamp.size == 0:
        return dict.fromkeys(keys)
    none = held < 0
    age = np.where(none, -1, (stamp - held) // period_ns)
    exact = np.where(none, True, (stamp - held) % period_ns == 0)
    counts = (
        np.count_nonzero(~none & exact & (age == 1)),
        np.count_nonzero(~none & exact & (age == 2)),
        np.count_nonzero(~none & exact & (age >= 3)),
        np.count_nonzero(none),
    )
    odd = stamp.size - sum(counts)
    values = [100.0 * c / stamp.size for c in (*counts, odd)]
    return dict(zip(keys, values + [values[0] + values[1]]))


def plant_figures(stamp_ns: np.ndarray, published_wall_ns: np.ndarray, period_ns: int) -> Figures:
    """Measure the simulated seconds per wall second over the published span.

    And the plant's publish-interval spread.
    """
    stamp = np.asarray(stamp_ns, dtype=np.int64)
    wall = np.asarray(published_wall_ns, dtype=np.int64)
    figures = _percentiles_us(np.diff(wall), 'plant_interval')
    figures['plant_samples'] = float(stamp.size)
    wall_span = int(wall[-1] - wall[0]) if wall.size > 1 else 0
    figures['speed_x'] = float((stamp[-1] - stamp[0]) / wall_span) if wall_span > 0 else None
    return figures


def coverage_figures(ctrl_stamp_ns: np.ndarray, plant_stamp_ns: np.ndarray) -> Figures:
    """Return what the controller's timing log covers.

    % of plant samples it answered, and the span of its stamps [s].
    """
    ctrl = np.asarray(ctrl_stamp_ns, dtype=np.int64)
    span_s = float((ctrl[-1] - ctrl[0]) / 1e9) if ctrl.size else 0.0
    plant_n = np.asarray(plant_stamp_ns).size
    return {
        'controlled_pct': 100.0 * ctrl.size / plant_n if plant_n else None,
        'controlled_span_s': span_s,
    }


def eso_figures(stats: dict) -> Figures:
    """ESO pairing from eso_stats.json.

    % of steps with the commanded current on time, and on time or repaired once the late command
    came (the state is then exactly the true pair's); substituted, refused.
    """
    steps = int(stats.get('steps', 0))
    exact, repaired = int(stats.get('exact_pairs', 0)), int(stats.get('repaired_pairs', 0))
    return {
        'eso_steps': float(steps),
        'eso_exact_pct': 100.0 * exact / steps if steps else None,
        'eso_exact_or_repaired_pct': 100.0 * (exact + repaired) / steps if steps else None,
        'eso_substituted': float(stats.get('substituted_pairs', 0)),
        'eso_repaired': float(repaired),
        'eso_refused': float(stats.get('refused_inputs', 0)),
    }


def error_ratios(figures: Figures, reference: Figures) -> Figures:
    """Tracking error of a run over the reference (sim-time) run's: max steady-state and RMS."""
    out: Figures = {}
    for key, ratio in (
        ('max_steady_error_rad', 'error_ratio_max_steady'),
        ('rms_error_rad', 'error_ratio_rms'),
    ):
        ours, ref = figures.get(key), reference.get(key)
        ok = (
            ours is not None
            and ref is not None
            and math.isfinite(ours)
            and math.isfinite(ref)
            and ref > 0
        )
        out[ratio] = ours / ref if ok else None
    return out


def process_figures(cpu_percent: dict, peak_rss_mb: dict) -> Figures:
    """CPU (% of one core) and peak resident memory (MB) per node.

    Keyed cpu_<node>_pct and rss_<node>_mb.
    """
    figures: Figures = {}
    for node in NODES:
        if node in peak_rss_mb:
            figures[f'cpu_{node}_pct'] = cpu_percent.get(node)
            figures[f'rss_{node}_mb'] = peak_rss_mb.get(node)
    return figures


def log_figures(run_dir: Path) -> Figures:
    """From the node logs: how many of plant, ESO, controller got SCHED_FIFO.

    1 if the controller latched safe stop.
    """
    launched = process_log(run_dir, 'launch')  # ros2 launch prefixes each line: [plant_node-4] ...
    texts = {
        node: process_log(run_dir, node)
        or '\n'.join(line for line in launched.splitlines() if line.startswith(f'[{node}_node-'))
        for node in ('plant', 'eso', 'controller')
    }
    return {
        'fifo_nodes': float(sum('running under SCHED_FIFO' in t for t in texts.values())),
        'safe_stop': float('safe stop latched' in texts['controller']),
    }


def run_dir_figures(run_dir: Path, mode: str, period_ns: int) -> Figures:
    """Every timing figure available from the files a run left in ``run_dir``."""
    figures: Figures = {}
    ctrl_path, plant_path, eso_path = (
        run_dir / 'controller_timing.npz',
        run_dir / 'plant_samples.npz',
        run_dir / 'eso_stats.json',
    )
    ctrl = dict(np.load(ctrl_path)) if ctrl_path.is_file() else None
    plant = dict(np.load(plant_path)) if plant_path.is_file() else None
    if ctrl is not None:
        figures['updates'] = float(ctrl['stamp_ns'].size)
        figures.update(period_figures(ctrl['received_wall_ns'], period_ns))
        figures['missed_samples'] = float(missed_samples(ctrl['stamp_ns'], period_ns))
        figures.update(_percentiles_us(ctrl['compute_ns'], 'compute'))
        if mode == 'realtime':
            figures.update(latency_figures(ctrl['latency_ns'], period_ns))
    if plant is not None and plant['stamp_ns'].size:
        figures.update(plant_figures(plant['stamp_ns'], plant['published_wall_ns'], period_ns))
        if ctrl is not None:
            figures.update(coverage_figures(ctrl['stamp_ns'], plant['stamp_ns']))
        figures.update(
            held_command_fractions(plant['stamp_ns'], plant['held_command_stamp_ns'], period_ns)
        )
        if ctrl is not None and mode == 'realtime':
            figures.update(
                latency_breakdown(
                    plant['stamp_ns'],
                    plant['published_wall_ns'],
                    ctrl['stamp_ns'],
                    ctrl['received_wall_ns'],
                    ctrl['latency_ns'],
                )
            )
    if eso_path.is_file():
        figures.update(eso_figures(json.loads(eso_path.read_text())))
    figures.update(log_figures(run_dir))
    return figures


def bag_figures(bag: Path) -> Figures:
    """Tracking error of a recorded run (actuator_bag.analyze).

    Max steady-state and RMS error, diverged.
    """
    from actuator_bag.analyze import analyze_run, load_run

    metrics = analyze_run(load_run(bag, quiet=True)).metrics
    return {
        'max_steady_error_rad': metrics.max_steady_error_rad,
        'rms_error_rad': metrics.rms_error_rad,
        'diverged': float(metrics.diverged),
    }


# --- offline core speed --------------------------------------------------------------------------


def offline_speed(scenario_name: str, batch: Optional[int], sim_s: float) -> float:
    """Total simulated seconds per wall second of ``ClosedLoop`` stepped for ``sim_s``.

    ``batch`` copies at once.
    """
    from actuator_sim.loop import ClosedLoop
    from actuator_sim.params_yaml import all_scenarios

    scenario = all_scenarios()[scenario_name]
    loop = ClosedLoop(scenario, batch=batch)
    steps = max(1, int(round(sim_s / scenario.common.dt_s)))
    start = time.perf_counter()
    for _ in range(steps):
        loop.step()
    wall_s = time.perf_counter() - start
    return steps * scenario.common.dt_s * (batch or 1) / wall_s


def offline_figures(scenario_name: str, batches: Sequence[int], sim_s: float) -> Figures:
    """Speed of the scalar ClosedLoop and of each batch size.

    Keyed offline_scalar_x and offline_batch_<n>_x.
    """
    figures: Figures = {'offline_scalar_x': offline_speed(scenario_name, None, sim_s)}
    for n in batches:
        figures[f'offline_batch_{n}_x'] = offline_speed(scenario_name, n, sim_s)
    return figures


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
    return [Row(f'cpu_{n}_pct', f'CPU {n}', '% core', '.1f', cpu) for n in NODES] + [
        Row(f'rss_{n}_mb', f'peak RSS {n}', 'MB', '.1f', rss) for n in NODES
    ]


def floor_rows() -> list[Row]:
    """Middleware floor lines (floor.py): one hop and the CPU of a node doing nothing but echo."""
    return [
        Row('floor_hop_p50_us', 'one hop (round trip / 2) p50', 'us'),
        Row('floor_hop_p99_us', 'one hop p99', 'us'),
        Row('floor_hop_max_us', 'one hop max', 'us'),
        Row('floor_lost_pct', 'messages not echoed', '%', '.3f'),
        Row('cpu_echo_pct', 'CPU echo (1 sub + 1 pub per sample)', '% core'),
        Row('cpu_source_pct', 'CPU source (1 pub + 1 sub per sample)', '% core'),
        Row('steal_pct', 'CPU steal by the hypervisor', '%', '.2f'),
    ]


def offline_rows(batches: Sequence[int]) -> list[Row]:
    """Offline speed lines."""
    return [Row('offline_scalar_x', 'scalar ClosedLoop', 'sim s/wall s', '.2f')] + [
        Row(f'offline_batch_{n}_x', f'ClosedLoop batch={n} (total)', 'sim s/wall s', '.2f')
        for n in batches
    ]


# --- table ---------------------------------------------------------------------------------------


def _cell(value: Optional[float], fmt: str) -> str:
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
                    _cell(s.median, row.fmt),
                    _cell(s.low, row.fmt),
                    _cell(s.high, row.fmt),
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


# --- runs ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Variant:
    """One way of running the nodes: mode, SCHED_FIFO priority (0 = normal) and CPU pinning."""

    mode: str
    rt_priority: int = 0
    pinned: bool = False
    launched: bool = False  # started by ros2 launch instead of the runner

    @property
    def slug(self) -> str:
        """Short name for folders and the CSV."""
        sched = f'fifo{self.rt_priority}' if self.rt_priority else 'normal'
        return (
            self.mode
            if self.mode == 'sim'
            else f'realtime_{sched}{"_pinned" if self.pinned else ""}'
            f'{"_launch" if self.launched else ""}'
        )

    @property
    def title(self) -> str:
        """Heading in the table."""
        if self.mode == 'sim':
            return 'sim: deterministic sim time (lockstep), normal scheduling'
        sched = (
            f'SCHED_FIFO {self.rt_priority}'
            if self.rt_priority
            else 'normal scheduling (SCHED_OTHER)'
        )
        return (
            f'realtime: {sched}'
            f'{", pinned (plant CPU 0; ESO, controller CPU 1)" if self.pinned else ""}'
            f'{", started by ros2 launch" if self.launched else ""}'
        )


def make_variants(
    modes: Sequence[str], rt_variants: Sequence[str], rt_priority: int
) -> list[Variant]:
    """Return the variants to run, sim first, in the order given."""
    variants = [Variant('sim')] if 'sim' in modes else []
    if 'realtime' in modes:
        for name in dict.fromkeys(rt_variants):
            variants.append(
                Variant(
                    'realtime',
                    rt_priority if 'fifo' in name else 0,
                    'pinned' in name,
                    'launch' in name,
                )
            )
    return variants


@dataclass
class RunRecord:
    """One finished (or failed) run with its figures."""

    variant: str
    repeat: int
    run_dir: Optional[str] = None
    bag: Optional[str] = None
    exit_codes: dict = field(default_factory=dict)
    error: Optional[str] = None
    figures: Figures = field(default_factory=dict)


@contextmanager
def progress(label: str, expected_s: float, quiet: bool) -> Iterator[None]:
    """Print '<label>: N s elapsed' every PROGRESS_EVERY_S seconds while the body runs."""
    stop = threading.Event()
    start = time.monotonic()

    def tick() -> None:
        while not stop.wait(PROGRESS_EVERY_S):
            print(
                f'[bench]   {label}: {time.monotonic() - start:.0f} s of ~{expected_s:.0f} s',
                flush=True,
            )

    thread = threading.Thread(target=tick, daemon=True)
    if not quiet:
        thread.start()
    try:
        yield
    finally:
        stop.set()


def expected_wall_s(variant: Variant, duration_s: float) -> float:
    """Rough wall time of a run for the progress lines.

    Start-up ~5 s; sim time at ~0.5x on a loaded 2-core VM.
    """
    return duration_s * (2.0 if variant.mode == 'sim' else 1.0) + 5.0


def cpu_times() -> tuple[float, float]:
    """(steal, total) CPU seconds of all CPUs.

    psutil; steal is 0 where the kernel does not report it.
    """
    times = psutil.cpu_times()
    return getattr(times, 'steal', 0.0), sum(times)


def steal_percent(before: tuple[float, float], after: tuple[float, float]) -> Optional[float]:
    """Share of CPU time the hypervisor gave to other guests [%].

    Between two cpu_times() readings.
    """
    total = after[1] - before[1]
    return 100.0 * (after[0] - before[0]) / total if total > 0 else None


def run_one(
    variant: Variant, repeat: int, args: argparse.Namespace, base: Path, period_ns: int
) -> RunRecord:
    """One recorded run of ``variant``; figures from its files and bag, or the error."""
    from actuator_tools.bringup import run_closed_loop, run_launched
    from actuator_tools.graph import PINNING

    record = RunRecord(variant.slug, repeat)
    where = f'{variant.slug}_rep{repeat}'
    label = f'{variant.slug} repeat {repeat}/{args.repeats}'
    times_before = cpu_times()
    try:
        with progress(label, expected_wall_s(variant, args.duration), args.quiet):
            result = (
                run_launched(
                    args.scenario,
                    variant.mode,
                    args.duration,
                    bag_root=base / 'bags' / where,
                    results_root=base / 'runs' / where,
                    thread_priority=variant.rt_priority,
                )
                if variant.launched
                else run_closed_loop(
                    args.scenario,
                    variant.mode,
                    args.duration,
                    record=True,
                    bag_root=base / 'bags' / where,
                    results_root=base / 'runs' / where,
                    quiet=True,
                    thread_priority=variant.rt_priority,
                    cpus=PINNING if variant.pinned else None,
                )
            )
    except SystemExit as exc:
        record.error = str(exc)
        return record
    record.run_dir, record.bag, record.exit_codes = (
        str(result.run_dir),
        str(result.bag),
        result.exit_codes,
    )
    if any(code != 0 for code in result.exit_codes.values()):
        record.error = f'node exit codes {result.exit_codes}; logs in {result.run_dir}'
    record.figures.update(run_dir_figures(result.run_dir, variant.mode, period_ns))
    record.figures.update(process_figures(result.cpu_percent, result.peak_rss_mb))
    record.figures['wall_s'] = result.wall_s
    record.figures['steal_pct'] = steal_percent(times_before, cpu_times())
    try:
        record.figures.update(bag_figures(result.bag))
    except (
        Exception
    ) as exc:  # a bag that cannot be analysed leaves the error figures out, not the run
        record.error = (
            record.error + '; ' if record.error else ''
        ) + f'bag analysis failed: {exc}'
    return record


def floor_run(args: argparse.Namespace, base: Path, repeat: int, rt_priority: int) -> Figures:
    """One middleware-floor run (actuator_tools.floor).

    Echo and source as processes for --floor-s seconds.
    """
    from actuator_tools.bringup import wait_for_leader
    from actuator_tools.floor import hop_figures
    from actuator_tools.supervisor import ProcessFigures, RosProcess

    run_dir = base / 'floor' / f'rep{repeat}'
    run_dir.mkdir(parents=True, exist_ok=True)
    output = run_dir / 'rtt.npz'
    priority = ['-p', f'thread_priority:={rt_priority}'] if rt_priority else []
    roles = {
        'echo': [],
        'source': ['-p', f'duration_s:={args.floor_s}', '-p', f'output:={output}'],
    }
    procs: dict[str, RosProcess] = {}
    figures_of: dict[str, ProcessFigures] = {}
    times_before = cpu_times()
    try:
        for role, params in roles.items():
            procs[role] = RosProcess(
                [
                    sys.executable,
                    '-m',
                    'actuator_tools.floor',
                    role,
                    '--ros-args',
                    *priority,
                    *params,
                ],
                log_dir=run_dir,
                name=role,
            )
            figures_of[role] = ProcessFigures(procs[role].pid)
        wait_for_leader(procs, figures_of, args.floor_s, quiet=True, leader='source')
    finally:
        codes = {role: proc.stop() for role, proc in procs.items()}
    if any(codes.values()) or not output.is_file():
        raise SystemExit(f'floor run failed (exit codes {codes}); logs in {run_dir}')
    with np.load(output) as rtt:
        figures = hop_figures(rtt['rtt_ns'], int(rtt['sent']))
    figures.update({f'cpu_{role}_pct': f.cpu_percent() for role, f in figures_of.items()})
    figures['steal_pct'] = steal_percent(times_before, cpu_times())
    return figures


def one_line(record: RunRecord) -> str:
    """Short progress summary of a finished run."""
    if record.error and not record.figures:
        return f'FAILED: {record.error}'
    f = record.figures
    parts = [f'wall {_cell(f.get("wall_s"), ".0f")} s']
    if record.variant == 'sim':
        parts.append(f'speed {_cell(f.get("speed_x"), ".2f")}x')
    if f.get('latency_p99_us') is not None:
        parts.append(
            f'period dev p99 {_cell(f.get("period_dev_p99_us"), ".0f")} us, '
            f'latency p99 {_cell(f.get("latency_p99_us"), ".0f")} us'
        )
    parts.append(f'max ss error {_cell(f.get("max_steady_error_rad"), ".3e")} rad')
    return ', '.join(parts) + (f' ({record.error})' if record.error else '')


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
        if r.variant == 'sim' and r.figures.get('max_steady_error_rad') is not None
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


def environment() -> dict:
    """Machine facts that explain the spread of the figures."""
    try:
        commit = (
            subprocess.run(
                ['git', 'rev-parse', 'HEAD'],
                capture_output=True,
                text=True,
                timeout=5,
                cwd=Path(__file__).resolve().parent,
            ).stdout.strip()
            or None
        )
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {
        'cpus': os.cpu_count(),
        'load_avg_1_5_15': list(os.getloadavg()),
        'kernel': platform.release(),
        'python': platform.python_version(),
        'rmw': os.environ.get('RMW_IMPLEMENTATION'),
        'ros_domain_id': os.environ.get('ROS_DOMAIN_ID'),
        'git_commit': commit,
        'rt_runtime_us_per_s': _read_int('/proc/sys/kernel/sched_rt_runtime_us'),
    }


def _read_int(path: str) -> Optional[int]:
    """Return an integer kernel setting (e.g. the SCHED_FIFO budget per second; -1 = unlimited).

    Or None.
    """
    try:
        return int(Path(path).read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def write_csv(path: Path, records: list[RunRecord], offline: list[Figures]) -> None:
    """One line per run (and per offline repeat) with every figure as a column."""
    rows = [
        {
            'variant': r.variant,
            'repeat': r.repeat,
            'run_dir': r.run_dir,
            'bag': r.bag,
            'error': r.error,
            **r.figures,
        }
        for r in records
    ]
    rows += [{'variant': 'offline', 'repeat': k + 1, **f} for k, f in enumerate(offline)]
    columns = list(dict.fromkeys(key for row in rows for key in row))
    with path.open('w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)


# --- CLI -----------------------------------------------------------------------------------------


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line on stderr and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        """Print 'bench: error: <message>' and exit 2."""
        self.exit(2, f'{self.prog}: error: {message}\n')


def build_parser() -> OneLineParser:
    """Return the command line."""
    p = OneLineParser(prog='bench', description=__doc__.splitlines()[0])
    p.add_argument(
        '--duration',
        type=float,
        default=60.0,
        metavar='S',
        help='length of each ROS run [s] (default 60; range '
        f'{DURATION_RANGE_S[0]:g}-{DURATION_RANGE_S[1]:g}; '
        'the steady-state error needs more than 5 s)',
    )
    p.add_argument(
        '--repeats',
        type=int,
        default=3,
        metavar='N',
        help='runs per variant (default 3); medians over them',
    )
    p.add_argument(
        '--scenario', default=DEFAULT_SCENARIO, help=f'paper scenario (default {DEFAULT_SCENARIO})'
    )
    p.add_argument(
        '--modes',
        nargs='+',
        choices=('realtime', 'sim'),
        default=['realtime', 'sim'],
        help='ROS modes to run (default both)',
    )
    p.add_argument(
        '--rt-variants',
        nargs='+',
        choices=RT_VARIANTS,
        default=['normal', 'fifo'],
        help='real-time variants: normal scheduling, SCHED_FIFO (--rt-priority), pinned to CPUs '
        '(bringup --pin layout), both, or SCHED_FIFO started by ros2 launch where it is installed '
        '(default: normal fifo)',
    )
    p.add_argument(
        '--rt-priority',
        type=int,
        default=50,
        metavar='P',
        help='SCHED_FIFO priority of plant, ESO and controller in the fifo variants (1-99, '
        'default 50)',
    )
    p.add_argument(
        '--skip-offline', action='store_true', help='skip the offline ClosedLoop speed measurement'
    )
    p.add_argument(
        '--floor-s',
        type=float,
        default=10.0,
        metavar='S',
        help='length of each middleware-floor run '
        '(echo of one message per sample, no control code) [s]; 0 skips it (default 10)',
    )
    p.add_argument(
        '--batches',
        type=int,
        nargs='+',
        default=[1, 10, 100, 1000],
        metavar='N',
        help='batch sizes of the offline speed measurement (default 1 10 100 1000)',
    )
    p.add_argument(
        '--offline-sim-s',
        type=float,
        default=5.0,
        metavar='S',
        help='simulated seconds per offline speed measurement (default 5)',
    )
    p.add_argument(
        '--out',
        type=Path,
        default=Path('results/bench'),
        help='results folder; each invocation writes <out>/<UTC timestamp>/ (default '
        'results/bench)',
    )
    p.add_argument('--quiet', action='store_true', help='no progress lines, only the table')
    return p


def check_args(args: argparse.Namespace) -> Optional[str]:
    """Return the first problem with the arguments, or None."""
    from actuator_sim.params_yaml import all_scenarios

    low, high = DURATION_RANGE_S
    if not low <= args.duration <= high:
        return f'--duration {args.duration:g} out of range [{low:g}, {high:g}] s'
    if not 1 <= args.repeats <= 100:
        return f'--repeats {args.repeats} out of range [1, 100]'
    if not 1 <= args.rt_priority <= 99:
        return f'--rt-priority {args.rt_priority} out of range [1, 99]'
    if any(not 1 <= n <= 100_000 for n in args.batches):
        return '--batches must be in [1, 100000]'
    if not (args.floor_s == 0.0 or 1.0 <= args.floor_s <= 600.0):
        return '--floor-s must be 0 (skip) or in [1, 600] s'
    if not 0.0 < args.offline_sim_s <= 600.0:
        return '--offline-sim-s must be in (0, 600] s'
    known = all_scenarios()
    if args.scenario not in known:
        return f'unknown scenario {args.scenario!r}; known: {", ".join(sorted(known))}'
    from actuator_tools.bringup import scenario_file

    try:
        scenario_file(args.scenario)
    except SystemExit as exc:
        return str(exc)
    return None


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the benchmark, print the table, write summary.json and runs.csv.

    1 if a run failed, 2 on bad input.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    problem = check_args(args)
    if problem:
        print(f'bench: error: {problem}', file=sys.stderr)
        return 2
    from actuator_sim.params_yaml import all_scenarios
    from actuator_core.timing import period_ns as to_period_ns

    period_ns = to_period_ns(all_scenarios()[args.scenario].common.dt_s)
    variants = make_variants(args.modes, args.rt_variants, args.rt_priority)
    base = args.out / dt.datetime.now(dt.timezone.utc).strftime('%Y%m%dT%H%M%SZ')
    base.mkdir(parents=True, exist_ok=True)
    env_start = environment()
    say = (lambda msg: None) if args.quiet else (lambda msg: print(f'[bench] {msg}', flush=True))
    say(
        f'{args.scenario}: {len(variants)} variant(s) x {args.repeats} repeat(s) of '
        f'{args.duration:g} s; '
        f'{env_start["cpus"]} CPUs, load {env_start["load_avg_1_5_15"][0]:.2f}; results in {base}'
    )
    records: list[RunRecord] = []
    offline: list[Figures] = []
    floor: list[Figures] = []
    floor_priority = args.rt_priority if any('fifo' in v for v in args.rt_variants) else 0
    interrupted = False
    try:
        total, k = len(variants) * args.repeats, 0
        for repeat in range(1, args.repeats + 1):
            for variant in variants:  # interleaved, so load changes spread over all variants
                k += 1
                say(
                    f'run {k}/{total}: {variant.title}, repeat {repeat}/{args.repeats} '
                    f'(~{expected_wall_s(variant, args.duration):.0f} s)'
                )
                record = run_one(variant, repeat, args, base, period_ns)
                records.append(record)
                say(f'  done: {one_line(record)}')
        if args.floor_s:
            for repeat in range(1, args.repeats + 1):
                say(
                    f'middleware floor {repeat}/{args.repeats}: echo at 1 kHz for '
                    f'{args.floor_s:g} s'
                )
                try:
                    floor.append(floor_run(args, base, repeat, floor_priority))
                except SystemExit as exc:
                    print(f'bench: {exc}', file=sys.stderr)
        if not args.skip_offline:
            for repeat in range(1, args.repeats + 1):
                say(
                    f'offline speed {repeat}/{args.repeats}: scalar and batch '
                    f'{", ".join(map(str, args.batches))}, '
                    f'{args.offline_sim_s:g} simulated s each'
                )
                offline.append(offline_figures(args.scenario, args.batches, args.offline_sim_s))
    except KeyboardInterrupt:
        interrupted = True
        print('bench: interrupted; summarising the runs made so far', file=sys.stderr)
    return report(
        args,
        variants,
        records,
        offline,
        base,
        period_ns,
        env_start,
        interrupted,
        floor,
        floor_priority,
    )


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


if __name__ == '__main__':
    sys.exit(main())
