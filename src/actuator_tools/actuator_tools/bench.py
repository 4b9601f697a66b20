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
import os
import platform
import shutil
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

from actuator_core import limits
from actuator_tools.bench_figures import (
    Figures,
    bag_figures,
    error_ratios,
    process_figures,
    run_dir_figures,
)
from actuator_tools.bench_table import (
    cell,
    floor_rows,
    format_table,
    offline_rows,
    realtime_rows,
    section_summary,
    sim_rows,
    spread,
)

DEFAULT_SCENARIO = 'case2_pp_nftsmc_eso'
RT_VARIANTS = (
    'normal',
    'fifo',
    'pinned',
    'fifo-pinned',
    'fifo-launch',
    'normal-composed',
    'fifo-composed',
)
#: Fast DDS publication modes a run can be given (RMW_FASTRTPS_PUBLICATION_MODE).
PUBLICATION_MODES = ('SYNCHRONOUS', 'ASYNCHRONOUS')
#: ROS modes: sim time across processes, sim time with the three nodes in one process, real time.
MODES = ('realtime', 'sim', 'sim-composed')
DURATION_RANGE_S = (1.0, 3600.0)
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


# --- runs ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Variant:
    """One way of running the nodes: mode, SCHED_FIFO priority (0 = normal) and CPU pinning."""

    mode: str
    rt_priority: int = 0
    pinned: bool = False
    launched: bool = False  # started by ros2 launch instead of the runner
    composed: bool = False  # joint, ESO and controller in one process (graph.compose)
    diagnostics_rate_hz: Optional[float] = None  # controller/state, plant/truth (None: default)
    publication_mode: str = ''  # RMW_FASTRTPS_PUBLICATION_MODE ('': the runner's)
    recorded: bool = True  # the recorder runs (its bag gives the tracking figures)

    @property
    def slug(self) -> str:
        """Short name for folders and the CSV."""
        sched = f'fifo{self.rt_priority}' if self.rt_priority else 'normal'
        composed = '_composed' if self.composed else ''
        base = (
            f'sim{composed}'
            if self.mode == 'sim'
            else f'realtime_{sched}{"_pinned" if self.pinned else ""}'
            f'{"_launch" if self.launched else ""}{composed}'
        )
        if self.diagnostics_rate_hz is not None:
            base += f'_diag{self.diagnostics_rate_hz:g}hz'
        if self.publication_mode:
            base += f'_{self.publication_mode.lower()}'
        return base if self.recorded else f'{base}_unrecorded'

    @property
    def title(self) -> str:
        """Heading in the table."""
        one = ', joint + ESO + controller in one process' if self.composed else ''
        if self.diagnostics_rate_hz is not None:
            rate = self.diagnostics_rate_hz
            one += f', controller/state and plant/truth at {f"{rate:g} Hz" if rate else "1 kHz"}'
        if self.publication_mode:
            one += f', Fast DDS {self.publication_mode.lower()} publication'
        if not self.recorded:
            one += ', no recorder'
        if self.mode == 'sim':
            return f'sim: deterministic sim time (lockstep), normal scheduling{one}'
        sched = (
            f'SCHED_FIFO {self.rt_priority}'
            if self.rt_priority
            else 'normal scheduling (SCHED_OTHER)'
        )
        return (
            f'realtime: {sched}'
            f'{", pinned (plant CPU 0; ESO, controller CPU 1)" if self.pinned else ""}'
            f'{", started by ros2 launch" if self.launched else ""}{one}'
        )


def missing_tool(variant: Variant) -> Optional[str]:
    """Say what a variant needs that this machine lacks, or None."""
    if variant.launched and shutil.which('ros2') is None:
        return 'ros2 launch is not installed (no ros2 on PATH)'
    return None


def make_variants(
    modes: Sequence[str],
    rt_variants: Sequence[str],
    rt_priority: int,
    diagnostics_rates: Sequence[float] = (),
    publication_modes: Sequence[str] = (),
    without_recorder: bool = False,
) -> list[Variant]:
    """Return the variants to run, sim first, in the order given.

    Each real-time variant runs once more per rate of ``diagnostics_rates``; every variant runs
    once per mode of ``publication_modes`` (none: the runner's own mode), and once more without
    the recorder if ``without_recorder``.
    """
    variants = [Variant('sim')] if 'sim' in modes else []
    if 'sim-composed' in modes:
        variants.append(Variant('sim', composed=True))
    if 'realtime' in modes:
        for name in dict.fromkeys(rt_variants):
            variant = Variant(
                'realtime',
                rt_priority if 'fifo' in name else 0,
                'pinned' in name,
                'launch' in name,
                'composed' in name,
            )
            variants.append(variant)
            variants += [
                dataclasses.replace(variant, diagnostics_rate_hz=float(rate))
                for rate in dict.fromkeys(diagnostics_rates)
            ]
    if publication_modes:
        variants = [
            dataclasses.replace(v, publication_mode=mode)
            for v in variants
            for mode in dict.fromkeys(publication_modes)
        ]
    if without_recorder:
        variants = [v for r in variants for v in (r, dataclasses.replace(r, recorded=False))]
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


def publication_mode_environment(mode: str) -> dict:
    """Environment that gives the nodes Fast DDS's publication ``mode`` ('': the runner's)."""
    from actuator_ros.realtime import PUBLICATION_MODE

    return {PUBLICATION_MODE[0]: mode} if mode else {}


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
    from actuator_tools.bringup import run_closed_loop, run_launched
    from actuator_tools.graph import PINNING

    record = RunRecord(variant.slug, repeat)
    where = f'{variant.slug}_rep{repeat}'
    label = f'{variant.slug} repeat {repeat}/{args.repeats}'
    times_before = cpu_times()
    try:
        with (
            progress(label, expected_wall_s(variant, args.duration), args.quiet),
            _environment(publication_mode_environment(variant.publication_mode)),
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
    from actuator_tools.bench_figures import hop_figures
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
        wait_for_leader(procs, figures_of, args.floor_s, quiet=True, leaders=['source'])
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
        choices=MODES,
        default=list(MODES),
        help='ROS modes to run: realtime, sim (separate processes), sim-composed (joint, ESO '
        'and controller in one process) (default all)',
    )
    p.add_argument(
        '--rt-variants',
        nargs='+',
        choices=RT_VARIANTS,
        default=['normal', 'fifo', 'fifo-composed'],
        help='real-time variants: normal scheduling, SCHED_FIFO (--rt-priority), pinned to CPUs '
        '(bringup --pin layout), both, SCHED_FIFO started by ros2 launch where it is installed, '
        'or the joint, ESO and controller in one process (-composed) '
        '(default: normal fifo fifo-composed)',
    )
    p.add_argument(
        '--diagnostics-rates',
        type=float,
        nargs='+',
        default=[],
        metavar='HZ',
        help='also run each real-time variant with controller/state and plant/truth at each '
        'rate (0: every sample; default: none, every sample as a recorded run has them)',
    )
    p.add_argument(
        '--publication-modes',
        nargs='+',
        choices=PUBLICATION_MODES,
        default=[],
        help="run every variant under each of Fast DDS's publication modes (default: the "
        "runner's, ASYNCHRONOUS; see actuator_ros.realtime.PUBLICATION_MODE)",
    )
    p.add_argument(
        '--without-recorder',
        action='store_true',
        help='run every variant once more without the recorder (no bag: no tracking figures; '
        'its CPU and latency as a run that records nothing)',
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
    low_hz, high_hz = limits.DIAGNOSTICS_RATE_RANGE_HZ
    if any(not low_hz <= r <= high_hz for r in args.diagnostics_rates):
        return f'--diagnostics-rates must be in [{low_hz:g}, {high_hz:g}] Hz'
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
    variants = []
    for variant in make_variants(
        args.modes,
        args.rt_variants,
        args.rt_priority,
        args.diagnostics_rates,
        args.publication_modes,
        args.without_recorder,
    ):
        why = missing_tool(variant)
        if why:
            print(f'bench: skipping {variant.slug}: {why}', file=sys.stderr)
        else:
            variants.append(variant)
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
                save_run(base, records, offline)
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
