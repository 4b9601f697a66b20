# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Figures of one benchmark run: pure functions of the files a run left (``bench``).

Each reads the controller's timing log, the plant's sample log, the observer's pairing counts,
the node logs or the bag, and returns a flat dict of figures; each figure's formula is in
docs/performance.md#figures-and-their-formulas.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Optional

import numpy as np

from actuator_bench.host_stalls import TIMEOUT_NS
from actuator_bringup.supervisor import process_log
from actuator_core.limits import STEADY_STATE_START_S
from actuator_core.stats import missed_samples, percentiles

#: The processes whose CPU and memory a run reports.
NODES = ('plant', 'eso', 'controller', 'recorder', 'loop')  # loop: the composed process

Figures = dict[str, Optional[float]]
#: The first seconds of a controller's timing log that ``period_max_after_start_us`` leaves out:
#: the loop's start (discovery, the first lifecycle transitions) stalls it for 50-70 ms here.
START_UP_S = 1.0


# --- figures of one run (pure functions of the logged arrays) -----------------------------------


def _percentiles_us(values_ns: np.ndarray, prefix: str) -> Figures:
    """p50, p99 and max of a nanosecond array, in microseconds, keyed ``<prefix>_p50_us`` etc."""
    return {
        f'{prefix}_{k.rsplit("_", 1)[1]}_us': v
        for k, v in percentiles(np.asarray(values_ns, dtype=float) / 1e3, prefix).items()
    }


def period_figures(received_wall_ns: np.ndarray, period_ns: int) -> Figures:
    """Summarise the controller tick periods (diff of arrival wall times).

    mean, p50/p99/max, p99 |deviation|, count > 2 periods; the max again without the log's
    first ``START_UP_S``.
    """
    arrivals_ns = np.asarray(received_wall_ns, dtype=np.int64)
    periods_ns = np.diff(arrivals_ns)
    figures = _percentiles_us(periods_ns, 'period')
    if periods_ns.size == 0:
        figures.update(
            period_mean_us=None,
            period_dev_p99_us=None,
            periods_over_2x=None,
            period_max_after_start_us=None,
        )
        return figures
    after_start = periods_ns[arrivals_ns[1:] - arrivals_ns[0] > START_UP_S * 1e9]
    figures['period_max_after_start_us'] = (
        float(after_start.max() / 1e3) if after_start.size else None
    )
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
    figures.update(steady_gap_figures(stamp, wall))
    return figures


def steady_gap_figures(stamp_ns: np.ndarray, published_wall_ns: np.ndarray) -> Figures:
    """Measure the joint's stalls in the tracking error's steady window (STEADY_STATE_START_S on).

    The longest wall interval between two published samples [ms], and how many exceed the
    controller's measurement timeout (host_stalls.TIMEOUT_NS; a stale input there: the error's
    usual outliers).
    """
    stamp = np.asarray(stamp_ns, dtype=np.int64)
    wall = np.asarray(published_wall_ns, dtype=np.int64)
    if stamp.size < 2:
        return {}
    steady = (stamp[1:] - stamp[0]) >= int(STEADY_STATE_START_S * 1e9)
    gaps = np.diff(wall)[steady]
    if not gaps.size:
        return {}
    return {
        'steady_gap_max_ms': float(gaps.max()) * 1e-6,
        'steady_gaps_beyond_timeout': float(np.count_nonzero(gaps > TIMEOUT_NS)),
    }


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
        out[ratio] = None
        if ours is not None and ref is not None and math.isfinite(ours) and math.isfinite(ref):
            out[ratio] = ours / ref if ref > 0 else None
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
    loop = [cpu_percent.get(n) for n in ('loop',) if n in cpu_percent] or [
        cpu_percent.get(n) for n in ('plant', 'eso', 'controller') if n in cpu_percent
    ]
    known = [v for v in loop if v is not None]
    if loop and len(known) == len(loop):
        figures['cpu_joint_loop_pct'] = float(sum(known))  # joint + ESO + controller, one or three
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
    composed = process_log(run_dir, 'loop')  # one process holds the three nodes
    fifo = 3 * ('running under SCHED_FIFO' in composed) if composed else None
    return {
        'fifo_nodes': float(
            sum('running under SCHED_FIFO' in t for t in texts.values()) if fifo is None else fifo
        ),
        'safe_stop': float('safe stop latched' in (texts['controller'] + composed)),
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
    """Tracking error of a recorded run (actuator_analysis.analyze).

    Max steady-state and RMS error, diverged; the samples whose observer input current was not
    the one the joint held (with plant/truth).
    """
    from actuator_analysis.analyze import analyze_run, load_run, observer_input

    report = analyze_run(load_run(bag, quiet=True))
    metrics = report.metrics
    figures: Figures = {
        'max_steady_error_rad': metrics.max_steady_error_rad,
        'rms_error_rad': metrics.rms_error_rad,
        'diverged': float(metrics.diverged),
    }
    inputs = observer_input(report.run)
    if inputs is not None:
        figures['observer_input_differing'] = float(inputs['differing'])
    return figures


def hop_figures(rtt_ns: np.ndarray, sent: int) -> dict[str, float | None]:
    """One-hop latency (round trip / 2) p50/p99/max [us].

    And the share of messages never echoed [%].
    """
    if sent <= 0:
        return {}
    out: dict[str, float | None] = {'floor_lost_pct': 100.0 * (sent - rtt_ns.size) / sent}
    if rtt_ns.size:
        hop_us = rtt_ns / 2e3
        out.update(
            {f'floor_hop_{k.split("_")[-1]}_us': v for k, v in percentiles(hop_us, 'hop').items()}
        )
    return out
