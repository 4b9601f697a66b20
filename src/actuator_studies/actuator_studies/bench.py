# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Throughput of studies: runs per second against batch size (one core) and against Ray workers.

Batch size: one chunk of b runs (depths spread over 0..2000 m, so every element differs) in
this process, b = each --batches value, plus the scalar (float) path of a single run for
reference. Workers: the same study of --runs runs in chunks of RUNS_PER_CHUNK on a local Ray
instance with N CPUs for each N; parallel efficiency E(N) = rate(N) / (N rate(1)). Ray's
start-up is timed apart and not counted in the rates. The load average is printed with the
figures: the machine is shared, and other work lowers them.
"""

from __future__ import annotations

import os
import time

import numpy as np
from tabulate import tabulate

from actuator_studies import distributed
from actuator_studies.runner import SweepSpec, run_chunk
from actuator_studies.space import BaseScenario, build_scenario
from actuator_sim.loop import ClosedLoop

#: Runs per Ray task in the worker measurement.
RUNS_PER_CHUNK = 32
#: Depth range [m] the benchmark's runs spread over.
BENCH_DEPTH_M = (0.0, 2000.0)


def _spec(runs: int, batch: int, duration_s: float) -> SweepSpec:
    """Return a depth study of ``runs`` runs in chunks of ``batch``."""
    return SweepSpec(
        BaseScenario(duration_s=duration_s),
        {'depth_m': np.linspace(*BENCH_DEPTH_M, runs)},
        batch=batch,
        seed=0,
    )


def scalar_rate(duration_s: float) -> float:
    """Measure the runs per second of one scalar ClosedLoop run (the nodes' float path)."""
    scenario = build_scenario(BaseScenario(duration_s=duration_s), {})
    start = time.perf_counter()
    ClosedLoop(scenario).run()
    return 1.0 / (time.perf_counter() - start)


def batch_rate(batch: int, duration_s: float) -> float:
    """Measure the runs per second of one vectorised chunk of ``batch`` runs in this process."""
    spec = _spec(batch, batch, duration_s)
    start = time.perf_counter()
    run_chunk(spec, 0)
    return batch / (time.perf_counter() - start)


def ray_rate(workers: int, runs: int, duration_s: float) -> tuple[float, float]:
    """Measure (runs per second, Ray start seconds) on a local Ray instance.

    Of ``runs`` runs on a local Ray instance with ``workers`` CPUs.
    """
    start = time.perf_counter()
    ray = distributed.start_ray(f'local:{workers}')
    started = time.perf_counter() - start
    try:
        spec = _spec(runs, RUNS_PER_CHUNK, duration_s)
        ray.get(ray.remote(lambda: 0).remote())  # a worker is up before the clock starts
        start = time.perf_counter()
        for _ in distributed.run_ray(ray, spec, range(spec.chunks)):
            pass
        return runs / (time.perf_counter() - start), started
    finally:
        ray.shutdown()


def run_bench(
    batches: list[int], workers: list[int], runs: int, duration_s: float, log=print
) -> dict:
    """Measure and print both tables; return the figures."""
    load_before = os.getloadavg()
    scalar = scalar_rate(duration_s)
    rows = [('scalar (1 run, float path)', 1, f'{scalar:.2f}', f'{scalar * duration_s:.1f}')]
    by_batch = {}
    for b in batches:
        rate = batch_rate(b, duration_s)
        by_batch[b] = rate
        rows.append(('vectorised chunk', b, f'{rate:.2f}', f'{rate * duration_s:.1f}'))
    log(
        f'Runs per second against batch size, one core ({duration_s:g} s simulated per run, 1 '
        'ms samples)'
    )
    log(
        tabulate(
            rows, headers=('path', 'batch', 'runs/s', 'simulated s per wall s'), tablefmt='github'
        )
    )
    by_workers, starts = {}, {}
    for n in workers:
        by_workers[n], starts[n] = ray_rate(n, runs, duration_s)
    base = by_workers.get(1)
    rows = [
        (
            n,
            f'{by_workers[n]:.2f}',
            f'{by_workers[n] / (n * base):.2f}' if base else '—',
            f'{starts[n]:.1f}',
        )
        for n in workers
    ]
    log(
        f'\nRuns per second against Ray workers (local instance, {runs} runs in chunks of '
        f'{RUNS_PER_CHUNK})'
    )
    log(
        tabulate(
            rows,
            headers=('workers', 'runs/s', 'parallel efficiency', 'Ray start s'),
            tablefmt='github',
        )
    )
    load_after = os.getloadavg()
    log(
        f'\nload average (1, 5, 15 min) before {load_before[0]:.2f} {load_before[1]:.2f} '
        f'{load_before[2]:.2f}, '
        f'after {load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f}; {os.cpu_count()} CPUs'
    )
    return {
        'duration_s': duration_s,
        'scalar_runs_per_s': scalar,
        'batch_runs_per_s': by_batch,
        'ray_runs_per_s': by_workers,
        'ray_start_s': starts,
        'parallel_efficiency': {n: by_workers[n] / (n * base) for n in workers} if base else {},
        'load_average_before': list(load_before),
        'load_average_after': list(load_after),
        'cpus': os.cpu_count(),
    }
