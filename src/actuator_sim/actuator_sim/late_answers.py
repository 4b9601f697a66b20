# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What a loop that answers late does, offline: ``python -m actuator_sim.late_answers``.

Under normal scheduling the observer and the controller sometimes take a measurement several
samples after the joint made it, for tens of ms at a time, without a gap that would start the
recovery policy (2-11 ms for 20-200 ms; docs/safety.md#late-answers). Their answers then reach the
joint late, and its command binding decides what it applies: a window of one sample (the newest
or the one before) refuses them, and the gate holds an older command for up to its timeout; the
timeout's window (``binding.late_window_samples``) applies the newest answer. This runs the
offline core (``ClosedLoop``'s objects) with the observer and controller ``lag`` samples behind
the joint, in bursts, under both windows, and prints the max steady-state error and the samples
the controller commanded at the current limit; a run that latched (following error beyond 0.5
rad) is reported as inf.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Optional, Sequence

import numpy as np

from actuator_core.binding import CommandBinding, late_window_samples
from actuator_core.limits import CURRENT_LIMIT_A, SAMPLE_TIME_S, STEADY_STATE_START_S
from actuator_core.timing import period_ns
from actuator_sim.loop import ClosedLoop
from actuator_sim.scenarios import paper_scenario


def lag_profile(
    samples: int,
    fraction: float,
    seed: int,
    lag_range: tuple[int, int] = (2, 10),
    burst_range: tuple[int, int] = (20, 200),
) -> np.ndarray:
    """Return, for each sample k, how many samples behind the joint the loop's answers are.

    A burst starts with probability ``fraction`` per sample, lasts ``burst_range`` samples and
    holds a lag in ``lag_range`` that changes by at most one sample per sample (the lag grows by
    one for each sample the observer and controller do not get to; they catch up at once).
    """
    rng = np.random.default_rng(seed)
    lag = np.zeros(samples, dtype=int)
    low, high = lag_range
    k = 0
    while k < samples:
        if rng.random() >= fraction:
            k += 1
            continue
        length = int(rng.integers(burst_range[0], burst_range[1] + 1))
        target, now = int(rng.integers(low, high + 1)), 0
        for j in range(k, min(samples, k + length)):
            if now >= target:
                target = int(np.clip(target + rng.integers(-1, 2), low, high))
            now = now + 1 if target > now else target
            lag[j] = now
        k += length
    return lag


def run_lagged(
    lag: np.ndarray, late_samples: Optional[int] = None, duration_s: float = 10.0
) -> tuple[float, int]:
    """Return (max |e| over [5 s, end) or inf if latched, samples commanded at the limit).

    The paper's fast deep-sea PP-NFTSMC-ESO run; at sample k the observer and controller take
    every sample up to k - ``lag[k]`` they have not taken, and the joint binds each answer with
    ``CommandBinding(late_samples)`` (None: the joint's default window) and offers what it accepts
    to its gate, valid from the sample it answers, as the joint node does.
    """
    loop = ClosedLoop(paper_scenario('late', 'pp_nftsmc_eso', 'fast', 'deep_sea', duration_s))
    period = loop.period_ns
    binding = CommandBinding(period, late_samples)
    start = int(round(STEADY_STATE_START_S / loop.scenario.common.dt_s))
    measured: list[float] = []
    taken, worst, at_limit = -1, 0.0, 0
    for k in range(loop.scenario.samples):
        now = k * period
        measured.append(loop.joint.read(now).position_rad)
        binding.produced(now)
        for j in range(taken + 1, k - int(lag[k]) + 1):
            stamp, taken = j * period, j
            loop.deliver_estimates(loop.pairing.add_measurement(stamp, measured[j]))
            sample = loop.assembly.add_measurement(stamp, measured[j], received_ns=now)
            if sample is None:
                continue
            if loop.assembly.latched is True:
                return math.inf, at_limit
            at_limit += int(abs(sample.current_a) >= CURRENT_LIMIT_A)
            if sample.output is not None and j >= start:
                worst = max(worst, abs(float(sample.output.error_rad)))
            if not binding.check(stamp, sample.safe_stop):
                valid_from = binding.valid_from_ns(stamp, sample.safe_stop, now)
                loop.gate.offer(sample.current_a, stamp, sample.safe_stop, valid_from)
            loop.deliver_estimates(loop.pairing.add_command(stamp, sample.current_a))
        held = loop.gate.hold(now)
        loop.joint.write(held.current_a, held.brake)
    return worst, at_limit


def main(argv: Sequence[str] | None = None) -> int:
    """Print max steady-state error and samples at the limit per burst rate, for both windows."""
    parser = argparse.ArgumentParser(prog='late_answers', description=__doc__.splitlines()[0])
    parser.add_argument(
        '--fractions',
        type=float,
        nargs='+',
        default=[0.0002, 0.0005, 0.001],
        metavar='P',
        help='probability that a burst of late answers starts at a sample',
    )
    parser.add_argument(
        '--max-lag', type=int, default=10, metavar='N', help='largest lag in a burst [samples]'
    )
    parser.add_argument('--seeds', type=int, default=3, metavar='N', help='runs per setting')
    parser.add_argument(
        '--duration', type=float, default=10.0, metavar='S', help='simulated seconds per run (> 5)'
    )
    args = parser.parse_args(argv)
    if (
        not all(0.0 <= p <= 0.1 for p in args.fractions)
        or not 2 <= args.max_lag <= 100
        or not 1 <= args.seeds <= 100
        or not STEADY_STATE_START_S < args.duration <= 600.0
    ):
        parser.error(
            'fractions in [0, 0.1], max-lag in [2, 100], seeds in [1, 100], duration in (5, 600] s'
        )
    samples = int(round(args.duration * 1000))
    windows = (1, late_window_samples(period_ns(SAMPLE_TIME_S)))  # the paper's 1 ms
    print(
        f'fast deep-sea PP-NFTSMC-ESO, {args.duration:g} s, lag 2-{args.max_lag} samples in '
        f'bursts of 20-200, {args.seeds} seeds: max steady-state error [rad] / samples at the '
        'limit (inf: latched)'
    )
    print(f'{"bursts":>7s} {"late":>6s}  ' + '  '.join(f'window {w} sample(s)' for w in windows))
    for fraction in args.fractions:
        lags = [
            lag_profile(samples, fraction, seed, (2, args.max_lag)) for seed in range(args.seeds)
        ]
        share = 100.0 * float(np.mean([(lag > 0).mean() for lag in lags]))
        cells = []
        for window in windows:
            runs = [run_lagged(lag, window, args.duration) for lag in lags]
            cells.append(' '.join(f'{e:.1e}/{n}' for e, n in runs))
        print(f'{fraction:7.4f} {share:5.1f}%  ' + '  '.join(cells))
    return 0


if __name__ == '__main__':
    sys.exit(main())
