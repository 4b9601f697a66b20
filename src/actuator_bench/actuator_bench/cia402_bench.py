# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Benchmark of the CiA 402 driver: CPU per cycle and the cycle timing held at 1 kHz and 500 Hz.

Starts ``cia402_sim_drive`` as a process of its own and runs the driver node (the joint node
holding a Cia402Joint) in this process, autostart, no controller (the gate holds the brake),
for ``--duration`` seconds per rate. Prints the share of the grid's samples published, missed
TPDOs, the publication delay of each sample after its instant t_k (wake-up lateness + RPDO +
SYNC + TPDO wait + publish; the sample log's published_wall_ns - stamp_ns), p50 / p99, and
this process's CPU per cycle (sampling thread, bus thread, heartbeat, rclpy). The drive
process is not counted (on hardware it is the drive). The load average is printed with them:
on a shared 2-core machine the figures depend on it.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import time
from typing import Sequence

import numpy as np
import psutil
import rclpy
from rclpy.executors import SingleThreadedExecutor

from actuator_bringup.supervisor import RosProcess
from actuator_cia402.launch_spec import driver_arguments, driver_parameters
from actuator_ros.realtime import RealtimeSettings


def run_rate(rate_hz: float, duration_s: float) -> dict:
    """One run of the driver at ``rate_hz`` for ``duration_s``; returns its figures."""
    from actuator_cia402.driver_node import Cia402DriverNode
    from actuator_cia402.joint import Cia402Joint

    period = 1.0 / rate_hz
    drive = RosProcess(
        [
            sys.executable,
            '-m',
            'actuator_cia402.sim_drive_main',
            '--port',
            '0',
            '--sync-period',
            repr(period),
        ],
        name=f'bench_drive_{int(rate_hz)}',
    )
    context = rclpy.Context()
    try:
        drive.wait_for_output(r'^drive 1 ready$', timeout=30)
        hub = re.search(r'bus hub on (\S+)', drive.stdout)
        assert hub is not None, 'the drive did not say where its bus hub is'
        address = hub.group(1)
        params = driver_parameters(
            simulated=True, channel=address, sample_time_s=period, stop_after_s=duration_s
        )
        rclpy.init(args=driver_arguments(params), context=context)
        node = Cia402DriverNode(context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        node.autostart()
        process = psutil.Process()
        deadline = time.monotonic() + duration_s + 30.0
        cpu_start = wall_start = None
        while not node.finished and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
            if cpu_start is None and node.configured and node.start_ns is not None:
                times = process.cpu_times()
                cpu_start, wall_start = times.user + times.system, time.monotonic()
        times = process.cpu_times()
        cpu_s = times.user + times.system - (cpu_start or 0.0)
        wall_s = time.monotonic() - (wall_start or time.monotonic())
        joint = node.joint
        assert isinstance(joint, Cia402Joint)  # the driver node's, still configured
        log = node.samples_log.array()
        delay_us = (log[:, 1] - log[:, 0]) / 1e3 if len(log) else np.array([np.nan])
        cycles = joint.cycles
        figures = {
            'rate_hz': rate_hz,
            'cycles': cycles,
            'samples': int(len(log)),
            'missed_tpdo': joint.missed,
            'samples_held_percent': 100.0 * len(log) / max(1, round(wall_s * rate_hz)),
            'delay_p50_us': float(np.percentile(delay_us, 50)),
            'delay_p99_us': float(np.percentile(delay_us, 99)),
            'process_cpu_per_cycle_us': 1e6 * cpu_s / max(1, cycles),
            'process_cpu_percent': 100.0 * cpu_s / max(wall_s, 1e-9),
        }
        node.halt()
        node._drop()
        executor.shutdown()
        node.destroy_node()
        return figures
    finally:
        context.try_shutdown()
        drive.stop()


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
        f'cia402 driver benchmark, {args.duration:g} s per rate, simulated drive process, '
        f'{os.cpu_count()} CPUs, {scheduling}'
    )
    for r in results:
        print(
            f'{r["rate_hz"]:6.0f} Hz  load {r["load_average_1_5_15"]}: samples {r["samples"]} '
            f'({r["samples_held_percent"]:.1f} % of the grid), missed TPDO {r["missed_tpdo"]}; '
            f'sample published after t_k p50 {r["delay_p50_us"]:.0f} us p99 '
            f'{r["delay_p99_us"]:.0f} us; process CPU {r["process_cpu_per_cycle_us"]:.0f} us per '
            f'cycle ({r["process_cpu_percent"]:.0f} % of a core)'
        )
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
