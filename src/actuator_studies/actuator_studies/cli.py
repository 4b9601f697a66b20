# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Command lines: ``sweep``, ``sweep-bench``, ``design_gains`` and ``sweep-compare``.

Bad input (an unknown quantity, an empty or inverted range, a sample count of 0, an
unreachable Ray address, an existing output folder without --resume, ...) ends the command
with one line on stderr and exit status 2, before anything is written.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Sequence

from actuator_controller.laws import CONTROLLER_NAMES
from actuator_controller.reference import REFERENCE_KINDS
from actuator_sim.scenarios import CONDITIONS
from actuator_studies.space import METHODS, StudyInputError


def _fail(prog: str, message: str) -> int:
    """Print one line on stderr; exit status 2."""
    print(f'{prog}: error: {message}', file=sys.stderr)
    return 2


def _scenario_arguments(parser: argparse.ArgumentParser) -> None:
    """Options shared by every command: the base scenario."""
    parser.add_argument('--controller', choices=CONTROLLER_NAMES, default='pp_nftsmc_eso')
    parser.add_argument('--reference', choices=REFERENCE_KINDS, default='fast')
    parser.add_argument(
        '--condition',
        choices=tuple(CONDITIONS),
        default='deep_sea',
        help='base working condition (depth_m / condition.* override it)',
    )
    parser.add_argument(
        '--duration', type=float, default=10.0, help='simulated seconds per run (default 10)'
    )


class _OneLineParser(argparse.ArgumentParser):
    """argparse whose usage errors are one line on stderr with exit 2."""

    def error(self, message: str):
        """One line, exit 2."""
        self.exit(2, f'{self.prog}: error: {message}\n')


def sweep_main(argv: Sequence[str] | None = None) -> int:
    """``sweep``: grid, Monte Carlo or Latin hypercube study of the closed loop."""
    from actuator_studies.distributed import ChunkFailed, InjectedFailure
    from actuator_studies.sweep import DEFAULT_BATCH, SweepRequest, run_sweep

    p = _OneLineParser(
        prog='sweep', description='Sweep scenario quantities through the vectorised closed loop.'
    )
    p.add_argument(
        '--vary',
        action='append',
        default=[],
        metavar='NAME=LOW:HIGH[:N]|V1,V2,...',
        help='a varied quantity '
        '(grid: N points or the listed values; mc/lhs: uniform on the range)',
    )
    p.add_argument(
        '--set', action='append', default=[], metavar='NAME=VALUE', help='a fixed quantity'
    )
    p.add_argument('--method', choices=METHODS, default='grid')
    p.add_argument('--samples', type=int, default=0, help='draws for mc/lhs')
    p.add_argument(
        '--seed', type=int, default=0, help="seed of the draws and of every run's encoder noise"
    )
    p.add_argument(
        '--batch', type=int, default=None, help='runs per vectorised ClosedLoop (default 8192)'
    )
    p.add_argument(
        '--chunk',
        type=int,
        default=0,
        help='runs per chunk: one task, one file, the unit of --resume (default: one batch)',
    )
    p.add_argument(
        '--repeat',
        type=int,
        default=1,
        help='runs per design point, each with its own noise seed (default 1)',
    )
    p.add_argument(
        '--gains', default='', help='gains YAML (as design_gains writes) instead of Table 4'
    )
    _scenario_arguments(p)
    p.add_argument(
        '--out', type=Path, required=True, help='output folder (must not exist, unless --resume)'
    )
    p.add_argument(
        '--resume', action='store_true', help='continue a study in --out, skipping finished chunks'
    )
    p.add_argument('--ray', default='', metavar='local:N|ADDRESS', help='run chunks as Ray tasks')
    p.add_argument(
        '--plot',
        default='',
        metavar='X,Y',
        help='the two quantities of the maps (default: first two)',
    )
    p.add_argument('--no-progress', action='store_true')
    p.add_argument(
        '--inject-failure', default='', help=argparse.SUPPRESS
    )  # tests: CHUNK:MODE:MARKER
    a = p.parse_args(argv)
    req = SweepRequest(
        vary=a.vary,
        set=a.set,
        method=a.method,
        samples=a.samples,
        seed=a.seed,
        batch=a.batch if a.batch is not None else DEFAULT_BATCH,
        chunk=a.chunk,
        repeat=a.repeat,
        controller=a.controller,
        reference=a.reference,
        condition=a.condition,
        duration_s=a.duration,
        gains=a.gains,
    )
    inject = None
    if a.inject_failure:
        chunk, mode, marker = a.inject_failure.split(':', 2)
        inject = InjectedFailure(int(chunk), marker, mode)
    try:
        summary = run_sweep(
            req,
            a.out,
            a.resume,
            a.ray,
            tuple(x for x in a.plot.split(',') if x),
            inject,
            progress=not a.no_progress,
        )
    except StudyInputError as exc:
        return _fail('sweep', str(exc))
    except ChunkFailed as exc:
        print(f'sweep: {exc}', file=sys.stderr)
        print('sweep: the finished chunks are kept; rerun with --resume', file=sys.stderr)
        return 1
    err = summary['max_steady_error_rad']
    print(
        f'sweep: {summary["runs"]} runs ({summary["chunks"]} chunks, '
        f'{summary["chunks_resumed"]} resumed), '
        f'{summary["diverged"]} diverged, {summary["saturated_runs"]} saturated, '
        f'{summary["envelope_violated_runs"]} left the envelope; max ss error median '
        f'{err.get("median", float("nan")):.3e} rad, max {err.get("max", float("nan")):.3e} rad'
    )
    ex = summary['execution']
    if 'wall_s' in ex:
        print(
            f'sweep: {ex["runs_this_call"]} runs in {ex["wall_s"]:.1f} s '
            f'({ex["runs_per_s"]:.1f} runs/s, '
            f'{ex["executor"]}, {ex["workers"]} worker(s)); load average '
            f'{ex["load_average"][0]:.2f}'
        )
    print(f'sweep: {a.out}/runs.parquet, {a.out}/summary.json, ' + ', '.join(summary['figures']))
    return 0


def bench_main(argv: Sequence[str] | None = None) -> int:
    """``sweep-bench``: runs per second against batch size (one core) and against Ray workers."""
    from actuator_studies.bench import run_bench
    from actuator_studies.sweep import DEFAULT_BATCH

    p = _OneLineParser(
        prog='sweep-bench', description='Throughput of the vectorised loop and of Ray workers.'
    )
    p.add_argument('--batches', default='1024,4096,8192', help='batch sizes on one core')
    p.add_argument('--workers', default='1,2', help="Ray worker counts ('' for none)")
    p.add_argument(
        '--runs-per-worker',
        type=int,
        default=4096,
        help='runs per Ray worker in each Ray measurement (the same for every worker count)',
    )
    p.add_argument('--duration', type=float, default=2.0, help='simulated seconds per run')
    p.add_argument(
        '--driver-tasks',
        type=int,
        default=0,
        help='no-op tasks to measure the driver overhead per task with (0: skip)',
    )
    p.add_argument('--json', type=Path, help='write the figures as JSON')
    a = p.parse_args(argv)
    try:
        batches = [int(x) for x in a.batches.split(',') if x]
        workers = [int(x) for x in a.workers.split(',') if x]
        if min(batches + workers) < 1 or a.runs_per_worker < 1 or a.driver_tasks < 0:
            raise StudyInputError('batch sizes, worker counts and --runs-per-worker must be >= 1')
        figures = run_bench(
            batches,
            workers,
            a.runs_per_worker,
            a.duration,
            a.driver_tasks,
            default_chunk=DEFAULT_BATCH,
        )
    except (StudyInputError, ValueError) as exc:
        return _fail('sweep-bench', str(exc))
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(figures, indent=2))
    return 0


def design_main(argv: Sequence[str] | None = None) -> int:
    """``design_gains``: robust PP-NFTSMC-ESO gains over an envelope, under a stability margin."""
    from actuator_studies.design import DEFAULT_CORNERS, DesignRequest, run_design
    from actuator_studies.distributed import ChunkFailed

    p = _OneLineParser(
        prog='design_gains', description='Robust PP-NFTSMC-ESO gain design (Optuna TPE).'
    )
    p.add_argument('--trials', type=int, default=48)
    p.add_argument(
        '--parallel', type=int, default=8, help='trials asked at once and run as one batch'
    )
    p.add_argument('--seed', type=int, default=0)
    p.add_argument(
        '--percentile',
        type=float,
        default=100.0,
        help='of the max ss error over the corners (100: worst)',
    )
    p.add_argument(
        '--target-radius', type=float, default=None, help='spectral radius bound at 0, 1, 2 delays'
    )
    p.add_argument(
        '--corner',
        action='append',
        default=[],
        metavar='NAME=V1,V2',
        help='envelope corners, the product of all (default: ' + ' x '.join(DEFAULT_CORNERS) + ')',
    )
    p.add_argument(
        '--set', action='append', default=[], metavar='NAME=VALUE', help='a fixed quantity'
    )
    _scenario_arguments(p)
    p.add_argument(
        '--noise-seeds', type=int, default=3, help='noise seeds per noisy corner in the search'
    )
    p.add_argument(
        '--validate-seeds', type=int, default=5, help='held-out noise seeds per noisy corner'
    )
    p.add_argument(
        '--validate-points',
        type=int,
        default=40,
        help='held-out Latin-hypercube points inside the corners (0: none)',
    )
    p.add_argument(
        '--storage', default='', help='Optuna journal file: the study resumes from it if it exists'
    )
    p.add_argument('--study-name', default='design_gains', help='study name in --storage')
    p.add_argument(
        '--joint',
        default='',
        metavar='FILE',
        help='design for an identified joint (bag_identify --params FILE): its model is the '
        "nominal one and the plant's, the corners default to command_delay_samples=0,2",
    )
    p.add_argument(
        '--prune',
        action='store_true',
        help='exact pruning over the cases: a trial worse than the best on the hard quarter '
        'of the cases is not run on the rest (worst case only)',
    )
    p.add_argument('--out', type=Path, required=True, help='output folder (must not exist)')
    p.add_argument(
        '--ray', default='', metavar='local:N|ADDRESS', help='evaluate trial batches as Ray tasks'
    )
    a = p.parse_args(argv)
    req = DesignRequest(
        trials=a.trials,
        parallel=a.parallel,
        seed=a.seed,
        percentile=a.percentile,
        target_radius=a.target_radius,
        corners=a.corner,
        settings=a.set,
        controller=a.controller,
        reference=a.reference,
        condition=a.condition,
        duration_s=a.duration,
        noise_seeds=a.noise_seeds,
        validate_seeds=a.validate_seeds,
        validate_points=a.validate_points,
        storage=a.storage,
        study_name=a.study_name,
        prune=a.prune,
        joint=a.joint,
    )
    try:
        report = run_design(req, a.out, a.ray)
    except StudyInputError as exc:
        return _fail('design_gains', str(exc))
    except ChunkFailed as exc:
        print(f'design_gains: {exc}', file=sys.stderr)
        return 1
    for part, table in [('in sample', report['in_sample'])] + [
        (f'held out ({v["what"]})', v) for v in report['validation'].values()
    ]:
        for label, row in table.items():
            if isinstance(row, dict):
                print(
                    f'design_gains: {part}, {label}: worst {row["worst_error_rad"]:.3e} rad, '
                    f'median {row["median_error_rad"]:.3e}, {row["failed_cases"]} of '
                    f'{row["cases"]} above 1e-2 rad, '
                    f'max saturated {row["max_saturated_fraction"]:.3f}'
                )
    print(f'design_gains: {report["gains_yaml"]}, {a.out}/design.json')
    return 0


def compare_main(argv: Sequence[str] | None = None) -> int:
    """``sweep-compare A B``.

    Exit 0 when two studies' runs.parquet are identical cell for cell (NaN == NaN).
    """
    import pyarrow.parquet as pq

    from actuator_studies.results import tables_identical

    p = _OneLineParser(prog='sweep-compare', description='Are two studies identical row for row?')
    p.add_argument('a', type=Path)
    p.add_argument('b', type=Path)
    args = p.parse_args(argv)
    try:
        a, b = (pq.read_table(x / 'runs.parquet') for x in (args.a, args.b))
    except OSError as exc:
        return _fail('sweep-compare', str(exc))
    same = tables_identical(a, b)
    print(
        f'sweep-compare: {a.num_rows} and {b.num_rows} rows, {len(a.column_names)} columns: '
        f'{"identical" if same else "DIFFERENT"}'
    )
    return 0 if same else 1
