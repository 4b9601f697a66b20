# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Performance benchmark of the closed loop (``make bench``): timing, latency, CPU, memory, speed.

Runs plant, ESO, controller and the recorder as separate processes (``bringup.run_closed_loop``)
in real time (normal scheduling and/or SCHED_FIFO) and in deterministic sim time, each
``--repeats`` times, plus the offline core's speed (scalar and batched ``ClosedLoop``). Every
figure is printed as the median over repeats with its min/max spread, next to the issue's
target and PASS/MISS; nothing is asserted. Raw per-run files, summary.json and runs.csv are
kept under ``--out/<UTC timestamp>/``. Each figure's formula:
docs/performance.md#figures-and-their-formulas.

The ROS domain is the caller's environment (ROS_DOMAIN_ID); this module never changes it.

This module is the command line and the order of the runs; the variants are in
``bench_variants``, a run and what is saved of it in ``bench_run``, a run's figures in
``bench_figures``, the table in ``bench_table`` and the summary in ``bench_report``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
from pathlib import Path
from typing import Optional, Sequence

from actuator_bench.bench_figures import Figures
from actuator_bench.bench_report import DOCS_BEGIN, one_line, report
from actuator_bench.bench_run import (
    RunRecord,
    environment,
    expected_wall_s,
    floor_run,
    offline_figures,
    run_one,
    save_run,
)
from actuator_bench.bench_variants import (
    MODES,
    PUBLICATION_MODES,
    RT_VARIANTS,
    TRANSPORTS,
    make_variants,
    missing_tool,
)
from actuator_core import limits
from actuator_sim.scenarios import PAPER_SCENARIO

DEFAULT_SCENARIO = PAPER_SCENARIO
DURATION_RANGE_S = (1.0, 3600.0)


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
        'and controller in one process), sim-composed-in-process (that process also writes the '
        'bag, no recorder process) (default all)',
    )
    p.add_argument(
        '--rt-variants',
        nargs='+',
        choices=RT_VARIANTS,
        default=['normal', 'fifo', 'fifo-composed', 'fifo-pinned-composed'],
        help='real-time variants: normal scheduling, SCHED_FIFO (--rt-priority), pinned to CPUs '
        '(bringup --pin layout), both, SCHED_FIFO started by ros2 launch where it is installed, '
        'or the joint, ESO and controller in one process (-composed; pinned: that process on '
        "the joint's CPU) (default: normal fifo fifo-composed fifo-pinned-composed)",
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
        "runner's: ASYNCHRONOUS under SCHED_FIFO, SYNCHRONOUS otherwise and in sim time; "
        'actuator_ros.realtime.PUBLICATION_MODES)',
    )
    p.add_argument(
        '--transports',
        nargs='+',
        choices=TRANSPORTS,
        default=[],
        help="run every real-time variant over each of Fast DDS's transports: udp (the "
        "runner's own, actuator_ros.middleware) and shared-memory (Fast DDS's default, shared "
        "memory and UDP); sim time keeps shared memory (default: the runner's, not named)",
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
    p.add_argument(
        '--docs',
        type=Path,
        default=None,
        metavar='MARKDOWN',
        help="also write the table between the bench-table markers of this file (the docs' "
        'one current table: docs/performance.md), after a run without failures',
    )
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
    if args.docs is not None and DOCS_BEGIN not in (
        args.docs.read_text() if args.docs.is_file() else ''
    ):
        return f'--docs {args.docs}: no file with a {DOCS_BEGIN} marker'
    if args.scenario not in known:
        return f'unknown scenario {args.scenario!r}; known: {", ".join(sorted(known))}'
    from actuator_bringup.runner import scenario_file

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
    from actuator_core.timing import period_ns as to_period_ns
    from actuator_sim.params_yaml import all_scenarios

    period_ns = to_period_ns(all_scenarios()[args.scenario].common.dt_s)
    variants = []
    for variant in make_variants(
        args.modes,
        args.rt_variants,
        args.rt_priority,
        args.diagnostics_rates,
        args.publication_modes,
        args.without_recorder,
        args.transports,
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
                    f'{args.floor_s:g} s, then a lone grid thread on CPU 0 and on any CPU'
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


if __name__ == '__main__':
    sys.exit(main())
