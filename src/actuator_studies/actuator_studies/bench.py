# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Throughput of studies: runs per second per core against batch size and against Ray workers.

Batch size: one chunk of b runs (depths spread over 0..2000 m, so every element differs) in
this process (one core), b = each --batches value, plus the scalar (float) path of a single
run for reference; rates are also given for 10 s runs (the rate scales with 1 / duration).
Workers: a study of --runs runs on a local Ray instance with N CPUs for each N, in chunks of
runs / (IN_FLIGHT_PER_CPU N) runs, one batch each; per-core rate = rate / N and parallel
efficiency E(N) = rate(N) / (N rate(1)). Ray's start-up is timed apart and not counted.
Driver: the driver's CPU seconds per task of ``stream_tasks`` (no-op tasks), extrapolated to a
1e6-run sweep at the default chunk, beside the cost of one ``ray.wait`` over every pending
reference (what the driver paid per finished chunk before backpressure). The load average is
printed with the figures: the machine is shared, and other work lowers them.
"""

from __future__ import annotations

import os
import time

import numpy as np
from tabulate import tabulate

from actuator_sim.loop import ClosedLoop
from actuator_studies import distributed
from actuator_studies.runner import SweepSpec, run_chunk
from actuator_studies.space import BaseScenario, build_scenario

#: Depth range [m] the benchmark's runs spread over.
BENCH_DEPTH_M = (0.0, 2000.0)
#: Runs of the sweep the driver overhead is extrapolated to.
DRIVER_SWEEP_RUNS = 1_000_000
#: Reference duration [s] the per-core rates are also quoted for.
REFERENCE_DURATION_S = 10.0
#: Length [s] of the one-run chunk each Ray worker runs before a timed sweep (imports, unpacking).
WARM_UP_DURATION_S = 0.05


def _spec(runs: int, batch: int, duration_s: float, chunk: int = 0) -> SweepSpec:
    """Return a depth study of ``runs`` runs in batches of ``batch``."""
    return SweepSpec(
        BaseScenario(duration_s=duration_s),
        {'depth_m': np.linspace(*BENCH_DEPTH_M, runs)},
        batch=batch,
        seed=0,
        chunk_runs=chunk,
    )


def scalar_rate(duration_s: float) -> float:
    """Measure the runs per second of one scalar ClosedLoop run (the nodes' float path)."""
    scenario = build_scenario(BaseScenario(duration_s=duration_s), {})
    start = time.perf_counter()
    ClosedLoop(scenario).run()
    return 1.0 / (time.perf_counter() - start)


def batch_rate(batch: int, duration_s: float) -> tuple[float, float]:
    """Measure (runs per wall second, runs per CPU second) of one batch of ``batch`` runs.

    On a shared machine the process gets part of a core: runs per CPU second is what one core
    does while it runs this process.
    """
    spec = _spec(batch, batch, duration_s)
    start, cpu = time.perf_counter(), time.process_time()
    run_chunk(spec, 0)
    return batch / (time.perf_counter() - start), batch / (time.process_time() - cpu)


def ray_spec(workers: int, runs_per_worker: int, duration_s: float) -> SweepSpec:
    """Return the timed sweep of ``workers`` Ray workers: the same chunks for every count.

    Weak scaling: each worker gets ``runs_per_worker`` runs in IN_FLIGHT_PER_CPU chunks (one
    batch each), so a second worker adds work rather than halving each worker's batch, which
    by itself costs per-run throughput (the batch table).
    """
    chunk = max(1, -(-runs_per_worker // distributed.IN_FLIGHT_PER_CPU))
    return _spec(chunk * distributed.IN_FLIGHT_PER_CPU * workers, chunk, duration_s, chunk)


def ray_rate(workers: int, runs_per_worker: int, duration_s: float) -> tuple[float, float]:
    """Measure (runs per second, Ray start seconds) on a local instance with ``workers`` CPUs."""
    start = time.perf_counter()
    ray = distributed.start_ray(f'local:{workers}')
    started = time.perf_counter() - start
    try:
        spec = ray_spec(workers, runs_per_worker, duration_s)
        # Every worker is up and has imported the project before the clock starts: one short
        # chunk per worker (a cold worker's first task unpacks py_modules and imports numpy and
        # the loop, about a second, which a 2 s-run bench would count as throughput).
        warm = _spec(workers, 1, WARM_UP_DURATION_S, 1)
        for _ in distributed.run_ray(ray, warm, range(warm.chunks)):
            pass
        start = time.perf_counter()
        for _ in distributed.run_ray(ray, spec, range(spec.chunks)):
            pass
        return spec.runs / (time.perf_counter() - start), started
    finally:
        ray.shutdown()


def _noop(i):
    """Return the argument: a task that does nothing (driver overhead)."""
    return i


def driver_overhead(tasks: int) -> dict:
    """Driver CPU seconds per task of stream_tasks, and of one ray.wait over ``tasks`` refs."""
    ray = distributed.start_ray('local:1')
    try:
        remote = ray.remote(_noop)
        ray.get(remote.remote(0))
        cpu = time.process_time()
        for _ in distributed.stream_tasks(ray, remote, ((i,) for i in range(tasks))):
            pass
        per_task = (time.process_time() - cpu) / tasks
        refs = [remote.remote(i) for i in range(tasks)]
        ray.get(refs)
        start = time.perf_counter()
        for _ in range(5):
            ray.wait(refs, num_returns=1)
        wait_all = (time.perf_counter() - start) / 5
    finally:
        ray.shutdown()
    return {'tasks': tasks, 'driver_cpu_s_per_task': per_task, 'wait_over_all_s': wait_all}


def run_bench(
    batches: list[int],
    workers: list[int],
    runs_per_worker: int,
    duration_s: float,
    driver_tasks: int = 0,
    default_chunk: int = 8192,
    log=print,
) -> dict:
    """Measure and print the tables; return the figures."""
    load_before = os.getloadavg()
    scale = duration_s / REFERENCE_DURATION_S  # runs/s of duration_s runs -> of 10 s runs
    scalar = scalar_rate(duration_s)
    rows = [('scalar (1 run, float path)', 1, f'{scalar:.2f}', f'{scalar * scale:.2f}', '')]
    by_batch, by_batch_cpu = {}, {}
    for b in batches:
        by_batch[b], by_batch_cpu[b] = batch_rate(b, duration_s)
        rows.append(
            (
                'vectorised batch',
                b,
                f'{by_batch[b]:.1f}',
                f'{by_batch[b] * scale:.1f}',
                f'{by_batch_cpu[b] * scale:.1f}',
            )
        )
    log(f'Runs per second on one core against batch size ({duration_s:g} s runs, 1 ms samples)')
    log(
        tabulate(
            rows,
            headers=(
                'path', 'batch', 'runs/s', 'runs/s, 10 s runs', 'runs per CPU s, 10 s runs',
            ),
            tablefmt='github',
        )
    )  # fmt: skip
    by_workers, starts = {}, {}
    for n in workers:
        by_workers[n], starts[n] = ray_rate(n, runs_per_worker, duration_s)
    base = by_workers.get(1)
    worker_rows = [
        (
            n,
            f'{by_workers[n]:.1f}',
            f'{by_workers[n] / n * scale:.1f}',
            f'{by_workers[n] / (n * base):.2f}' if base else '-',
            f'{starts[n]:.1f}',
        )
        for n in workers
    ]
    if workers:
        chunk = ray_spec(1, runs_per_worker, duration_s).batch
        log(
            f'\nAgainst Ray workers (local instance, {runs_per_worker} runs of {duration_s:g} s '
            f'per worker in chunks of {chunk}: the same work per worker for every count)'
        )
        log(
            tabulate(
                worker_rows,
                headers=(
                    'workers', 'runs/s', 'per core, 10 s runs', 'parallel efficiency',
                    'Ray start s',
                ),
                tablefmt='github',
            )
        )  # fmt: skip
    driver = None
    if driver_tasks:
        driver = driver_overhead(driver_tasks)
        chunks = -(-DRIVER_SWEEP_RUNS // default_chunk)
        driver['sweep_runs'] = DRIVER_SWEEP_RUNS
        driver['chunk_runs'] = default_chunk
        driver['extrapolated_driver_s'] = chunks * driver['driver_cpu_s_per_task']
        log(
            f'\nDriver: {driver["driver_cpu_s_per_task"] * 1e3:.2f} ms CPU per task '
            f'({driver_tasks} no-op tasks, backpressure); a {DRIVER_SWEEP_RUNS:.0e}-run sweep '
            f'in chunks of {default_chunk} ({chunks} tasks): '
            f'{driver["extrapolated_driver_s"]:.1f} driver s. One ray.wait over '
            f'{driver_tasks} references (the old loop paid one per finished chunk): '
            f'{driver["wait_over_all_s"] * 1e3:.2f} ms'
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
        'batch_runs_per_s_per_core': by_batch,
        'batch_runs_per_cpu_s': by_batch_cpu,
        'ray_runs_per_s': by_workers,
        'ray_start_s': starts,
        'parallel_efficiency': {n: by_workers[n] / (n * base) for n in workers} if base else {},
        'driver': driver,
        'load_average_before': list(load_before),
        'load_average_after': list(load_after),
        'cpus': os.cpu_count(),
    }
