# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Runs of the benchmark (``bench``): one variant, the middleware floor, the offline core speed.

Each run of the closed loop is measured (CPU steal over it, the nodes' CPU and memory) and its
figures are read from the files it left (``bench_figures``). Every finished run is written to
runs.jsonl and runs.csv as it ends; ``environment`` gives the machine facts that explain the
spread of the figures.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
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

from actuator_bench.bench_figures import (
    Figures,
    bag_figures,
    process_figures,
    run_dir_figures,
)
from actuator_bench.bench_variants import Variant

PROGRESS_EVERY_S = 15.0


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


# --- runs ----------------------------------------------------------------------------------------


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


def publication_mode_environment(mode: str) -> dict:
    """Environment that gives the nodes Fast DDS's publication ``mode`` ('': the runner's)."""
    from actuator_ros.realtime import PUBLICATION_MODE_VARIABLE

    return {PUBLICATION_MODE_VARIABLE: mode} if mode else {}


def transport_environment(transport: str) -> dict:
    """Environment for a transport of bench_variants.TRANSPORTS ('': the runner's)."""
    from actuator_ros.middleware import SHARED_MEMORY_ENVIRONMENT

    return dict(SHARED_MEMORY_ENVIRONMENT) if transport == 'shared-memory' else {}


@contextmanager
def _environment(values: dict):
    """Set ``values`` in os.environ for the processes started inside; restore them after."""
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def run_one(
    variant: Variant, repeat: int, args: argparse.Namespace, base: Path, period_ns: int
) -> RunRecord:
    """One recorded run of ``variant``; figures from its files and bag, or the error."""
    from actuator_bringup.run_description import PINNING
    from actuator_bringup.runner import run_closed_loop, run_launched

    record = RunRecord(variant.slug, repeat)
    where = f'{variant.slug}_rep{repeat}'
    label = f'{variant.slug} repeat {repeat}/{args.repeats}'
    times_before = cpu_times()
    try:
        with (
            progress(label, expected_wall_s(variant, args.duration), args.quiet),
            _environment(
                publication_mode_environment(variant.publication_mode)
                | transport_environment(variant.transport)
            ),
        ):
            result = (
                run_launched(
                    args.scenario,
                    variant.mode,
                    args.duration,
                    bag_root=base / 'bags' / where,
                    results_root=base / 'runs' / where,
                    thread_priority=variant.rt_priority,
                    diagnostics_rate_hz=variant.diagnostics_rate_hz,
                    record=variant.recorded,
                )
                if variant.launched
                else run_closed_loop(
                    args.scenario,
                    variant.mode,
                    args.duration,
                    record=variant.recorded,
                    bag_root=base / 'bags' / where,
                    results_root=base / 'runs' / where,
                    quiet=True,
                    thread_priority=variant.rt_priority,
                    cpus=PINNING if variant.pinned else None,
                    composed=variant.composed,
                    diagnostics_rate_hz=variant.diagnostics_rate_hz,
                    record_in_process=variant.in_process,
                )
            )
    except SystemExit as exc:
        record.error = str(exc)
        return record
    except Exception as exc:  # noqa: BLE001 - one run's failure is its error, not the bench's end
        record.error = f'run failed: {type(exc).__name__}: {exc}'
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
    if not variant.recorded:
        return record
    assert result.bag is not None  # a recorded variant
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
    """One middleware-floor run (actuator_bench.floor).

    Echo and source as processes for --floor-s seconds.
    """
    from actuator_bench.bench_figures import hop_figures
    from actuator_bringup.runner import wait_for_leader
    from actuator_bringup.supervisor import ProcessFigures, RosProcess

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
                    'actuator_bench.floor',
                    role,
                    '--ros-args',
                    *priority,
                    *params,
                ],
                log_dir=run_dir,
                name=role,
            )
            figures_of[role] = ProcessFigures(procs[role].pid)
        wait_for_leader(procs, figures_of, args.floor_s, quiet=True, leaders=['source'])
    finally:
        codes = {role: proc.stop() for role, proc in procs.items()}
    if any(codes.values()) or not output.is_file():
        raise SystemExit(f'floor run failed (exit codes {codes}); logs in {run_dir}')
    with np.load(output) as rtt:
        figures = hop_figures(rtt['rtt_ns'], int(rtt['sent']))
    figures.update({f'cpu_{role}_pct': f.cpu_percent() for role, f in figures_of.items()})
    figures['steal_pct'] = steal_percent(times_before, cpu_times())
    for cpu, label in HOST_PROBES:
        figures.update(host_stall_run(args.floor_s, rt_priority, cpu, label, run_dir))
    return figures


#: The host floor's runs (actuator_bench.host_stalls): on CPU 0, where a pinned composed loop
#: runs, and on any CPU, as separate processes do; (cpu, the figures' prefix).
HOST_PROBES = ((0, 'host_cpu0'), (None, 'host_any'))


def host_stall_run(
    duration_s: float, rt_priority: int, cpu: Optional[int], label: str, run_dir: Path
) -> Figures:
    """One host-floor run: a lone grid thread's late wake-ups, figures prefixed ``label``."""
    cmd = [sys.executable, '-m', 'actuator_bench.host_stalls', '--duration', f'{duration_s:g}']
    cmd += ['--priority', str(rt_priority)] + ([] if cpu is None else ['--cpu', str(cpu)])
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=duration_s + 60.0)
    (run_dir / f'{label}.stderr').write_text(done.stderr)
    if done.returncode != 0:
        print(f'bench: host floor {label} failed: {done.stderr.strip()}', file=sys.stderr)
        return {}
    figures = json.loads(done.stdout)
    return {key.replace('host', label, 1): value for key, value in figures.items()}


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


def save_run(base: Path, records: list[RunRecord], offline: list[Figures]) -> None:
    """Write the runs finished so far (runs.jsonl, runs.csv) as each ends.

    A later crash or interruption loses none of them.
    """
    with (base / 'runs.jsonl').open('a') as f:
        f.write(json.dumps(dataclasses.asdict(records[-1]), default=str) + '\n')
    write_csv(base / 'runs.csv', records, offline)


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
