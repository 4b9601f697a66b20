"""Bring up plant, ESO, controller (and the recorder) as separate processes: ``bringup``.

Where ``ros2 launch`` exists (a Jazzy installation), ``launch/closed_loop.launch.py`` does
the same. Here, without launch, this starts the same installed executables, found through
the ament index as ``ros2 run`` finds them, with the scenario's parameter file, waits for
the plant to finish the run, stops the rest with SIGINT (escalating to SIGTERM, SIGKILL),
and measures each process' CPU and peak memory from /proc.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from ament_index_python.packages import PackageNotFoundError, get_package_prefix, get_package_share_directory

from actuator_sim.params_yaml import all_scenarios
from actuator_ros.runtime import MODES

CLK_TCK = os.sysconf('SC_CLK_TCK')


def executable(package: str, name: str) -> Path:
    """<prefix>/lib/<package>/<name> through the ament index, as ``ros2 run`` resolves it."""
    try:
        path = Path(get_package_prefix(package)) / 'lib' / package / name
    except PackageNotFoundError:
        raise SystemExit(f'bringup: package {package!r} is not installed (build the workspace first)') from None
    if not os.access(path, os.X_OK):
        raise SystemExit(f'bringup: {path} is missing or not executable')
    return path


def scenario_file(scenario: str) -> Path:
    """share/actuator_bringup/config/<scenario>.yaml."""
    path = Path(get_package_share_directory('actuator_bringup')) / 'config' / f'{scenario}.yaml'
    if not path.is_file():
        names = sorted(p.stem for p in path.parent.glob('*.yaml'))
        raise SystemExit(f'bringup: no scenario {scenario!r}; installed: {", ".join(names)}')
    return path


#: CPU layout of ``--pin`` on a 2-core machine: the ESO and the controller work in strict
#: sequence each sample (command -> estimate -> command), so they share a core; the plant
#: (and, unpinned, the recorder) use the other.
PINNING = {'plant': '0', 'eso': '1', 'controller': '1'}


def scenario_duration(scenario: str) -> float:
    """The paper scenario's run length [s] (10 s for any other parameter file)."""
    known = all_scenarios().get(scenario)
    return known.duration_s if known is not None else 10.0


@dataclass
class NodeProcess:
    """One node process with its log and /proc readings."""

    name: str
    popen: subprocess.Popen
    log: Path
    started_wall: float = field(default_factory=time.monotonic)
    cpu_ticks_at_mark: int | None = None
    wall_at_mark: float | None = None
    cpu_ticks_last: int = 0
    wall_last: float = 0.0
    peak_rss_kb: int = 0

    def sample(self) -> None:
        """Read CPU ticks and peak RSS from /proc while the process lives."""
        try:
            stat = Path(f'/proc/{self.popen.pid}/stat').read_text().rsplit(')', 1)[1].split()
            self.cpu_ticks_last = int(stat[11]) + int(stat[12])
            self.wall_last = time.monotonic()
            for line in Path(f'/proc/{self.popen.pid}/status').read_text().splitlines():
                if line.startswith('VmHWM:'):
                    self.peak_rss_kb = int(line.split()[1])
        except (OSError, IndexError, ValueError):
            pass

    def mark(self) -> None:
        """Start of the measured interval (after start-up and imports)."""
        self.sample()
        self.cpu_ticks_at_mark, self.wall_at_mark = self.cpu_ticks_last, self.wall_last

    def cpu_percent(self) -> float | None:
        """CPU use since ``mark`` in % of one core."""
        if self.wall_at_mark is None or self.wall_last <= self.wall_at_mark:
            return None
        return 100.0 * (self.cpu_ticks_last - self.cpu_ticks_at_mark) / CLK_TCK / (self.wall_last - self.wall_at_mark)

    def stop(self, timeout_s: float = 10.0) -> int:
        """SIGINT, then SIGTERM, then SIGKILL; returns the exit code."""
        for sig, wait in ((signal.SIGINT, timeout_s), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0)):
            if self.popen.poll() is not None:
                break
            self.sample()
            self.popen.send_signal(sig)
            try:
                self.popen.wait(wait)
            except subprocess.TimeoutExpired:
                continue
        return self.popen.wait()


@dataclass
class RunResult:
    """What a bring-up produced."""

    name: str
    mode: str
    bag: Path | None
    run_dir: Path
    timing_log: Path
    exit_codes: dict[str, int]
    cpu_percent: dict[str, float | None]
    peak_rss_mb: dict[str, float]
    wall_s: float


def recorder_parameters(mode: str) -> dict[str, str | int]:
    """The recorder's queue for a closed-loop run in ``mode`` (bringup and the launch file both use it).

    realtime: BEST_EFFORT, 5 s of queue per topic. The recorder keeps normal scheduling, and the
    queue rides out the bursts in which the SCHED_FIFO loop leaves it no CPU. Under SCHED_FIFO as
    well, the real-time threads used ~90 % of both cores, past the kernel's default budget
    (sched_rt_runtime_us = 950000 per second), and the kernel then stopped every one of them for
    the rest of the second: gaps of 27-63 ms in the plant's sampling. Measured, 3 runs each way:
    longest gap 17-43 ms -> 5-18 ms, latency p99 1.4-2.5 -> 0.9-1.9 ms; one of those runs
    overflowed the 1 s queue it had then (8 % of messages reported lost by the middleware).
    sim: RELIABLE like the publishers, and 10 s of queue. The lockstep runs as fast as the CPU
    allows and does not wait for the recorder, which then falls behind by more than a 1 s queue:
    2 s PI runs lost 68-669 of 2000 samples in 12 of 94 runs (best effort or reliable, several
    middleware settings), 0 of 32 with 10 s.
    """
    if mode == 'sim':
        return {'reliability': 'reliable', 'queue_depth': 10000}
    return {'reliability': 'best_effort', 'queue_depth': 5000}


def run_closed_loop(scenario: str, mode: str, duration_s: float | None = None, record: bool = True,
                    bag_root: Path = Path('bags'), results_root: Path = Path('results/runs'),
                    executor: str = 'events', extra_params: Sequence[str] = (), quiet: bool = False,
                    rt_priority: int = 0, cpus: dict[str, str] | None = None) -> RunResult:
    """Start the nodes for ``scenario`` in ``mode``, run to the end, stop everything, return the result.

    ``duration_s`` None runs the scenario's own length (10 s for the paper's cases), never forever.
    ``rt_priority`` > 0 runs the ESO and controller under SCHED_FIFO at that priority and the plant
    one level above; the recorder keeps normal scheduling. ``cpus`` pins nodes to
    CPUs by key ('plant', 'eso', 'controller'), e.g. {'plant': '0', 'eso': '1', 'controller': '1'}.
    """
    cpus = cpus or {}
    if duration_s is None:
        duration_s = scenario_duration(scenario)
    if mode not in MODES:
        raise SystemExit(f'bringup: mode must be one of {", ".join(MODES)}')
    params = scenario_file(scenario)
    stamp = dt.datetime.now(dt.timezone.utc).strftime('%Y%m%dT%H%M%SZ')
    name = f'{scenario}_{mode}_{stamp}'
    run_dir = results_root / name
    run_dir.mkdir(parents=True, exist_ok=True)
    bag = bag_root / name if record else None
    sim = mode == 'sim'
    timing_log = run_dir / 'controller_timing.npz'
    def node_args(priority: int) -> list[str]:
        return ['--executor', executor, *(['--rt-priority', str(priority)] if priority else []),
                '--ros-args', '--params-file', str(params), '-p', f'mode:={mode}']
    clocked = ['-p', f'use_sim_time:={"true" if sim else "false"}']
    plan = []
    if bag is not None:
        bag_root.mkdir(parents=True, exist_ok=True)
        recorder = [a for k, v in recorder_parameters(mode).items() for a in ('-p', f'{k}:={v}')]
        plan.append(('recorder', 'actuator_bag', 'recorder', ['--ros-args', '-p', f'output:={bag}', *recorder, *clocked]))
    def pinned(key: str) -> list[str]:
        # The plant is the sampling hardware: it runs one level above the ESO and controller, so
        # its tick is not queued behind their callbacks (measured, 3 runs of 20 s each way: latency
        # p99 1.51 -> 0.94 ms, plant tick late p99 1.35 -> 0.42 ms, latched runs 1/3 -> 0/3).
        priority = min(rt_priority + 1, 99) if key == 'plant' and rt_priority else rt_priority
        return (['--cpus', cpus[key]] if key in cpus else []) + node_args(priority)

    plan += [('controller', 'actuator_controller', 'controller_node',
              pinned('controller') + clocked + ['-p', f'timing_log:={timing_log}', *extra_params]),
             ('eso', 'actuator_eso', 'eso_node',
              pinned('eso') + clocked + ['-p', f'stats_log:={run_dir / "eso_stats.json"}', *extra_params])]
    plant_args = pinned('plant') + ['-p', f'wait_for_subscribers:={3 if bag else 2}',
                                    '-p', f'timing_log:={run_dir / "plant_samples.npz"}']
    if duration_s is not None:
        plant_args += ['-p', f'stop_after_s:={duration_s}']
    plan.append(('plant', 'actuator_plant', 'plant_node', plant_args))
    procs: dict[str, NodeProcess] = {}
    start = time.monotonic()
    try:
        for key, package, exe, args in plan:
            log = run_dir / f'{key}.log'
            popen = subprocess.Popen([str(executable(package, exe)), *args], stdout=log.open('w'),
                                     stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True)
            procs[key] = NodeProcess(key, popen, log)
        if not quiet:
            print(f'[bringup] {scenario} in {mode} mode: {", ".join(procs)} started; logs in {run_dir}', flush=True)
        wait_for_leader(procs, duration_s, quiet)
    finally:
        codes = {key: proc.stop() for key, proc in reversed(list(procs.items()))}
    wall = time.monotonic() - start
    return RunResult(name, mode, bag, run_dir, timing_log, codes,
                     {k: p.cpu_percent() for k, p in procs.items()},
                     {k: p.peak_rss_kb / 1024.0 for k, p in procs.items()}, wall)


def wait_for_leader(procs: dict[str, NodeProcess], duration_s: float | None, quiet: bool,
                    leader: str = 'plant') -> None:
    """Poll until the leader (the plant) exits at the end of the run; mark CPU baselines when it logs 'sampling started'."""
    plant = procs[leader]
    marked = False
    deadline = time.monotonic() + (max(120.0, 30.0 * duration_s) if duration_s else float('inf'))
    last_note = time.monotonic()
    while plant.popen.poll() is None:
        for proc in procs.values():
            proc.sample()
        if not marked and 'sampling started' in plant.log.read_text(errors='replace'):
            for proc in procs.values():
                proc.mark()
            marked = True
        for key, proc in procs.items():
            if key != leader and proc.popen.poll() is not None:
                raise SystemExit(f'bringup: {key} exited early with code {proc.popen.returncode}; see {proc.log}')
        if time.monotonic() > deadline:
            raise SystemExit('bringup: the run did not finish in time; see the logs')
        if not quiet and time.monotonic() - last_note > 5.0:
            print(f'[bringup] running ({time.monotonic() - plant.started_wall:.0f} s)', flush=True)
            last_note = time.monotonic()
        time.sleep(0.2)


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: one closed-loop run of a scenario, optionally recorded to bags/."""
    parser = argparse.ArgumentParser(prog='bringup', description=__doc__.splitlines()[0])
    parser.add_argument('--scenario', default='case2_pp_nftsmc_eso',
                        help='installed scenario (share/actuator_bringup/config/<name>.yaml)')
    parser.add_argument('--mode', choices=MODES, default='realtime')
    parser.add_argument('--duration', type=float, default=None,
                        help='run length [s] (default: the paper scenario\'s, 10 s)')
    parser.add_argument('--no-record', action='store_true', help='do not start the recorder')
    parser.add_argument('--bags', type=Path, default=Path('bags'), help='folder for bags (default bags/)')
    parser.add_argument('--executor', choices=('events', 'single_threaded'), default='events')
    parser.add_argument('--rt-priority', type=int, default=0, metavar='N',
                        help='SCHED_FIFO priority of plant, ESO and controller (0 = normal scheduling)')
    parser.add_argument('--pin', action='store_true',
                        help='pin the plant to CPU 0 and the ESO and controller (which run in sequence) to CPU 1')
    args = parser.parse_args(argv)
    if args.duration is not None and not 0.0 < args.duration <= 3600.0:
        parser.error('--duration must be in (0, 3600] s')
    duration = args.duration if args.duration is not None else scenario_duration(args.scenario)
    result = run_closed_loop(args.scenario, args.mode, duration, not args.no_record, args.bags,
                             executor=args.executor, rt_priority=args.rt_priority,
                             cpus=PINNING if args.pin else None)
    print(json.dumps({'bag': str(result.bag), 'exit_codes': result.exit_codes, 'cpu_percent': result.cpu_percent,
                      'peak_rss_mb': result.peak_rss_mb}, indent=1))
    return 0 if all(code == 0 for code in result.exit_codes.values()) else 1


if __name__ == '__main__':
    sys.exit(main())
