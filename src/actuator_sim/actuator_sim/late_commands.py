# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What late commands do to the loop, offline: ``python -m actuator_sim.late_commands``.

In real time a command sometimes misses its sample, and the plant holds the previous current over
it. The ESO can then integrate the current the controller commanded (what the ESO node and
controller achieve by repairing the estimate, docs/concepts/architecture.md#sample-timing) or the
one the plant held. This runs the offline core (``ClosedLoop``) with the plant one sample late on
random samples, in bursts, both ways, and prints the max steady-state error; a run beyond the
controller's following-error limit (0.5 rad) is reported as latched.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Sequence

import numpy as np

from actuator_core.limits import FOLLOWING_ERROR_LIMIT_RAD
from actuator_core.metrics import STEADY_STATE_START_S
from actuator_sim.loop import ClosedLoop
from actuator_sim.scenarios import paper_scenario


def late_mask(samples: int, fraction: float, burst: int, seed: int) -> np.ndarray:
    """Return which samples' commands are late.

    Bursts of ``burst`` samples starting with probability ``fraction``.
    """
    rng = np.random.default_rng(seed)
    mask = np.zeros(samples, dtype=bool)
    left = 0
    for k in range(samples):
        if left == 0 and rng.random() < fraction:
            left = burst
        if left:
            mask[k] = True
            left -= 1
    return mask


def max_steady_error(
    mask: np.ndarray, eso_integrates_applied: bool, duration_s: float = 10.0
) -> float:
    """Return max |e| over [5 s, end), inf if latched.

    Of the paper's fast deep-sea PP-NFTSMC-ESO run with ``mask``'s late commands.
    """
    loop = ClosedLoop(paper_scenario('late', 'pp_nftsmc_eso', 'fast', 'deep_sea', duration_s))
    start = int(round(STEADY_STATE_START_S / loop.scenario.common.dt_s))
    worst = 0.0
    for k in range(loop.scenario.samples):
        error = abs(float(loop.step(bool(mask[k]), eso_integrates_applied)['error_rad']))
        if not math.isfinite(error) or error > FOLLOWING_ERROR_LIMIT_RAD:
            return math.inf
        if k >= start:
            worst = max(worst, error)
    return worst


def main(argv: Sequence[str] | None = None) -> int:
    """Print max steady-state error per late fraction and burst.

    ESO integrating commanded vs held current.
    """
    parser = argparse.ArgumentParser(prog='late_commands', description=__doc__.splitlines()[0])
    parser.add_argument(
        '--fractions',
        type=float,
        nargs='+',
        default=[0.02, 0.05, 0.1, 0.2],
        metavar='P',
        help='probability that a burst of late commands starts at a sample',
    )
    parser.add_argument(
        '--bursts', type=int, nargs='+', default=[1, 3], metavar='N', help='samples per burst'
    )
    parser.add_argument(
        '--seeds', type=int, default=3, metavar='N', help='random runs per setting'
    )
    parser.add_argument(
        '--duration', type=float, default=10.0, metavar='S', help='simulated seconds per run (> 5)'
    )
    args = parser.parse_args(argv)
    if (
        not all(0.0 <= p <= 1.0 for p in args.fractions)
        or not all(1 <= b <= 1000 for b in args.bursts)
        or not 1 <= args.seeds <= 100
        or not STEADY_STATE_START_S < args.duration <= 600.0
    ):
        parser.error(
            'fractions in [0, 1], bursts in [1, 1000], seeds in [1, 100], duration in (5, 600] s'
        )
    samples = int(round(args.duration * 1000))
    print(
        f'max steady-state error [rad], fast deep-sea PP-NFTSMC-ESO, {args.duration:g} s, '
        f'{args.seeds} seeds '
        f'(inf = beyond {FOLLOWING_ERROR_LIMIT_RAD} rad, latched)'
    )
    print(
        f'{"late":>6s} {"burst":>5s} {"late samples":>12s}  '
        f'{"ESO integrates commanded u(k)":32s} ESO integrates held u(k-1)'
    )
    for fraction in args.fractions:
        for burst in args.bursts:
            masks = [late_mask(samples, fraction, burst, seed) for seed in range(args.seeds)]
            commanded = [max_steady_error(m, False, args.duration) for m in masks]
            held = [max_steady_error(m, True, args.duration) for m in masks]
            share = 100.0 * float(np.mean([m.mean() for m in masks]))
            print(
                f'{fraction:6.2f} {burst:5d} {share:11.1f}%  '
                f'{" ".join(f"{e:9.2e}" for e in commanded):32s} '
                f'{" ".join(f"{e:9.2e}" for e in held)}'
            )
    return 0


if __name__ == '__main__':
    sys.exit(main())
