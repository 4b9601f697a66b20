# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The benchmark of two versions of the project in one invocation: a commit and the tree now.

    python scripts/bench_before_after.py [--before REV] [--rounds N] [--duration S]
        [--rt-variant fifo|normal]

The commit ``REV`` (default: the last one before the one joint node, issue 20) is extracted to
``build/before/<sha>/``, built there by its own ``scripts/build.sh`` with this tree's
virtual environment (its lock files pin a subset of today's), and each round runs the
benchmark of both versions, each its own ``python -m actuator_bench.bench`` (the same
figures: CPU per node from /proc, sensor-to-command latency from the controller's timing log,
the lockstep's speed), one after the other, the order swapped every round so that a drift of
the machine's load falls on both. Prints the medians over the rounds side by side with the
load averages; writes ``<out>/<UTC timestamp>/before_after.json``. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Optional, Sequence

ROOT = Path(__file__).resolve().parent.parent
#: ``--rt-variant`` -> the bench's variant name in summary.json.
REALTIME_VARIANTS = {'fifo': 'realtime_fifo50', 'normal': 'realtime_normal'}
#: The parent of 6f5780e, which brought the one joint node (actuator_ros.joint_node).
BEFORE_JOINT_NODE = '4a95bb9'
#: (variant in summary.json, figure, label) compared; every figure a median over the rounds
#: (realtime_fifo50: SCHED_FIFO priority 50, the bench's default; ``--rt-variant normal`` reads
#: realtime_normal instead).
FIGURES = (
    ('realtime_fifo50', 'cpu_plant_pct', 'CPU plant (joint) [% of a core]'),
    ('realtime_fifo50', 'cpu_eso_pct', 'CPU ESO [%]'),
    ('realtime_fifo50', 'cpu_controller_pct', 'CPU controller [%]'),
    ('realtime_fifo50', 'latency_p50_us', 'sensor-to-command latency p50 [us]'),
    ('realtime_fifo50', 'latency_p99_us', 'sensor-to-command latency p99 [us]'),
    ('realtime_fifo50', 'max_steady_error_rad', 'max steady error, real time [rad]'),
    ('sim', 'speed_x', 'lockstep speed [x real time]'),
    ('sim', 'cpu_plant_pct', 'CPU plant (joint), lockstep [%]'),
)


def build_parser() -> argparse.ArgumentParser:
    """Return the command line."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        '--before', default=BEFORE_JOINT_NODE, help='the earlier commit (default %(default)s)'
    )
    p.add_argument('--rounds', type=int, default=3, help='runs of each version (default 3)')
    p.add_argument('--duration', type=float, default=20.0, help='seconds per run (default 20)')
    p.add_argument('--out', type=Path, default=ROOT / 'results' / 'bench-before-after')
    p.add_argument(
        '--rt-variant',
        choices=REALTIME_VARIANTS,
        default='fifo',
        help='the real-time runs: SCHED_FIFO 50 or normal scheduling (default %(default)s)',
    )
    p.add_argument(
        '--table', type=Path, metavar='DIR', help='only print the table of an earlier invocation'
    )
    return p


def prepare(rev: str) -> Path:
    """Extract and build commit ``rev`` in build/before/<sha>/; return its tree."""
    sha = subprocess.run(
        ['git', '-C', str(ROOT), 'rev-parse', '--short', f'{rev}^{{commit}}'],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    tree = ROOT / 'build' / 'before' / sha
    if not (tree / 'scripts').is_dir():
        tree.mkdir(parents=True, exist_ok=True)
        archive = subprocess.Popen(
            ['git', '-C', str(ROOT), 'archive', sha], stdout=subprocess.PIPE
        )
        subprocess.run(['tar', '-x', '-C', str(tree)], stdin=archive.stdout, check=True)
        if archive.wait() != 0:
            raise SystemExit(f'bench_before_after: git archive {sha} failed')
    venv = tree / '.venv'
    if not venv.exists():
        venv.symlink_to(ROOT / '.venv')
    subprocess.run(['bash', 'scripts/build.sh'], cwd=tree, check=True)
    return tree


def run_bench(tree: Path, out: Path, duration_s: float, rt_variant: str = 'fifo') -> dict:
    """One benchmark of the version in ``tree`` (sim, and real time as ``rt_variant`` says)."""
    out.mkdir(parents=True, exist_ok=True)
    command = (
        'source scripts/env.sh && exec python -m actuator_bench.bench --modes realtime sim '
        f'--rt-variants {rt_variant} --repeats 1 --duration {duration_s:g} --skip-offline '
        f'--floor-s 0 --quiet --out {out}'
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith(('AMENT_', 'COLCON_'))}
    env.pop('PYTHONPATH', None)
    subprocess.run(['bash', '-c', command], cwd=tree, env=env, check=False)
    summaries = sorted(out.glob('*/summary.json'))
    if not summaries:
        return {}
    return json.loads(summaries[-1].read_text())


def figures_of(summary: dict, realtime: str = REALTIME_VARIANTS['fifo']) -> dict:
    """{(variant, figure): value} of one benchmark's runs; ``realtime``: its real-time variant.

    The real-time figures are filed under FIGURES' name (realtime_fifo50) whichever it was.
    """
    out = {}
    for run in summary.get('runs', []):
        for variant, figure, _ in FIGURES:
            value = run.get('figures', {}).get(figure)
            ran = realtime if variant == REALTIME_VARIANTS['fifo'] else variant
            if run.get('variant') == ran and value is not None:
                out[variant, figure] = float(value)
    return out


def table(rounds: dict) -> list[str]:
    """Lines of the side-by-side table: median and range over the rounds, after / before."""
    lines = [f'{"figure":40s} {"before":>26s} {"after":>26s} {"after/before":>12s}']
    for variant, figure, label in FIGURES:
        cells, medians = [], []
        for version in ('before', 'after'):
            values = [f[variant, figure] for f in rounds[version] if (variant, figure) in f]
            if values:
                medians.append(statistics.median(values))
                cells.append(f'{medians[-1]:.4g} ({min(values):.3g}-{max(values):.3g})')
            else:
                medians.append(None)
                cells.append('-')
        ratio = f'{medians[1] / medians[0]:.2f}' if None not in medians and medians[0] else '-'
        lines.append(f'{label:40s} {cells[0]:>26s} {cells[1]:>26s} {ratio:>12s}')
    return lines


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Build the earlier version, run both in alternation, print and write the table."""
    args = build_parser().parse_args(argv)
    realtime = REALTIME_VARIANTS[args.rt_variant]
    if args.table:  # rounds as the folders name them: round<r>_<version>/<stamp>/summary.json
        rounds = {
            v: [
                figures_of(json.loads(f.read_text()), realtime)
                for f in sorted(args.table.glob(f'round*_{v}/*/summary.json'))
            ]
            for v in ('before', 'after')
        }
        print('\n'.join(table(rounds)))
        return 0
    before = prepare(args.before)
    base = args.out / time.strftime('%Y%m%dT%H%M%SZ', time.gmtime())
    trees = {'before': before, 'after': ROOT}
    rounds: dict = {'before': [], 'after': []}
    loads = []
    for r in range(1, args.rounds + 1):
        order = ('before', 'after') if r % 2 else ('after', 'before')
        for version in order:
            loads.append(os.getloadavg()[0])
            print(f'[round {r}] {version}: {trees[version]}', flush=True)
            summary = run_bench(
                trees[version], base / f'round{r}_{version}', args.duration, args.rt_variant
            )
            rounds[version].append(figures_of(summary, realtime))
    lines = table(rounds)
    header = (
        f'before = {args.before} ({before}), after = the tree now; {args.rounds} rounds of '
        f"{args.duration:g} s each, real time {realtime}; 1-min load at the runs' starts "
        f'{min(loads):.1f}-{max(loads):.1f} on {os.cpu_count()} CPUs'
    )
    print('\n' + header + '\n' + '\n'.join(lines))
    (base / 'before_after.json').write_text(
        json.dumps(
            {
                'header': header,
                'table': lines,
                'rounds': {
                    v: [{f'{k[0]}:{k[1]}': x for k, x in f.items()} for f in fs]
                    for v, fs in rounds.items()
                },
                'loads': loads,
            },
            indent=1,
        )
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
