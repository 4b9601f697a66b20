# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Benchmark of the CiA 402 driver: CPU per cycle and the cycle timing held at 1 kHz and 500 Hz.

Runs the real driver node in this process (simulated drive on the virtual bus, autostart,
no controller: the gate holds 0 A) for ``--duration`` seconds per rate, and prints medians
and 99th percentiles of: the cycle thread's CPU per cycle (thread time: RPDO + SYNC + TPDO
decoding + publish), the wall time of a cycle (SYNC to TPDO1 handled: includes the simulated
drive's step in its bus thread), the wake-up lateness against the SYNC grid, and the process's
CPU per cycle (all threads: cycle, both bus threads, the simulated drive's joint model, rclpy).
The load average is printed with them: on a shared 2-core machine the figures depend on it.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from typing import Sequence

import psutil
import rclpy
from rclpy.executors import SingleThreadedExecutor

from actuator_cia402.launch_spec import driver_arguments, driver_parameters
from actuator_ros.realtime import RealtimeSettings


def run_rate(rate_hz: float, duration_s: float) -> dict:
    """One run of the driver at ``rate_hz`` for ``duration_s``; returns its figures."""
    from actuator_cia402.driver_node import Cia402DriverNode

    params = driver_parameters(
        simulated=True,
        sync_period_s=1.0 / rate_hz,
        stop_after_s=duration_s,
        channel=f'bench_{os.getpid()}_{int(rate_hz)}',
    )
    context = rclpy.Context()
    rclpy.init(args=driver_arguments(params), context=context)
    try:
        node = Cia402DriverNode(context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        process = psutil.Process()
        deadline = time.monotonic() + duration_s + 30.0
        cpu_start = None
        while not node.finished and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
            if cpu_start is None and node.cycle is not None:
                times = process.cpu_times()
                cpu_start, wall_start = times.user + times.system, time.monotonic()
        times = process.cpu_times()
        cpu_s, wall_s = (
            times.user + times.system - (cpu_start or 0.0),
            time.monotonic() - (wall_start or 0.0),
        )
        stats = node._last_stats
        figures = {
            'rate_hz': rate_hz,
            'cycles': stats.cycles,
            'missed_tpdo': stats.missed_feedback,
            'overruns': stats.overruns,
            'skipped_cycles': stats.skipped_cycles,
            'cycles_held_percent': 100.0 * stats.cycles / max(1, round(wall_s * rate_hz)),
            'process_cpu_per_cycle_us': 1e6 * cpu_s / max(1, stats.cycles),
            'process_cpu_percent': 100.0 * cpu_s / max(wall_s, 1e-9),
            **stats.medians_us(),
        }
        node.close()
        executor.shutdown()
        node.destroy_node()
        return figures
    finally:
        context.try_shutdown()


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: ``cia402_bench [--duration S] [--rates 1000 500] [--json]``."""
    parser = argparse.ArgumentParser(prog='cia402_bench', description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=5.0, help='seconds per rate (default 5)')
    parser.add_argument(
        '--rates', type=float, nargs='+', default=[1000.0, 500.0], help='SYNC rates [Hz]'
    )
    parser.add_argument('--json', action='store_true', help='print JSON instead of a table')
    parser.add_argument(
        '--rt-priority',
        type=int,
        default=0,
        metavar='N',
        help='run under SCHED_FIFO at priority N (1-99; 0 = normal scheduling)',
    )
    args = parser.parse_args(argv)
    if not 0.5 <= args.duration <= 600.0:
        parser.error('--duration must be in [0.5, 600] s')
    if not 0 <= args.rt_priority <= 99:
        parser.error('--rt-priority must be in [0, 99]')
    scheduling = 'normal scheduling'
    if args.rt_priority:
        refused = RealtimeSettings(thread_priority=args.rt_priority).apply()
        scheduling = refused or f'SCHED_FIFO priority {args.rt_priority}'
    results = []
    for rate in args.rates:
        load = os.getloadavg()
        figures = run_rate(rate, args.duration)
        figures['load_average_1_5_15'] = [round(x, 2) for x in load]
        results.append(figures)
    if args.json:
        print(json.dumps(results, indent=1))
        return 0
    print(
        f'cia402 driver benchmark, {args.duration:g} s per rate, simulated drive, '
        f'{os.cpu_count()} CPUs, {scheduling}'
    )
    for r in results:
        print(
            f'{r["rate_hz"]:6.0f} Hz  load {r["load_average_1_5_15"]}: cycles {r["cycles"]} '
            f'({r["cycles_held_percent"]:.1f} % of the grid), missed TPDO {r["missed_tpdo"]}, '
            f'overruns {r["overruns"]}'
        )
        print(
            f'          cycle thread CPU p50 {r["cpu_p50_us"]:.0f} us '
            f'p99 {r["cpu_p99_us"]:.0f} us; '
            f'SYNC->TPDO cycle wall p50 {r["cycle_wall_p50_us"]:.0f} us '
            f'p99 {r["cycle_wall_p99_us"]:.0f} us'
        )
        print(
            f'          wake-up late p50 {r["late_p50_us"]:.0f} us p99 {r["late_p99_us"]:.0f} us; '
            f'process CPU {r["process_cpu_per_cycle_us"]:.0f} us per cycle '
            f'({r["process_cpu_percent"]:.0f} % of a core)'
        )
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
