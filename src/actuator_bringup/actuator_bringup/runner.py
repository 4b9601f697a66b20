# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Bring up a closed-loop run as separate processes: ``bringup`` (the runner).

The processes and their parameters come from ``actuator_bringup.run_description.closed_loop``, the
same description the launch file uses (``ros2 launch actuator_bringup closed_loop.launch.py`` on a
Jazzy installation). Here, without launch, the runner starts the installed executables (found as
``ros2 run`` finds them) with the scenario's parameter file and ``autostart:=true``, waits for the
joint (plant or driver) to finish the run, stops the rest with SIGINT (escalating to SIGTERM,
SIGKILL), and reads each process' CPU and peak memory. SIGINT or SIGTERM to the runner stops every
node it started before it exits.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

from ament_index_python.packages import get_package_share_directory

from actuator_core import limits
from actuator_sim.params_yaml import all_scenarios
from actuator_bringup.run_description import (
    JOINTS,
    LIVE_DIAGNOSTICS_RATE_HZ,
    MAX_JOINTS_ON_BUS,
    PINNING,
    closed_loop,
    default_scenario,
    node_kind,
    ros_arguments,
)
from actuator_bringup.composition import compose
from actuator_bringup.supervisor import ProcessFigures, RosProcess

MODES = ('realtime', 'sim')


def scenario_file(scenario: str) -> Path:
    """share/actuator_bringup/config/<scenario>.yaml."""
    path = Path(get_package_share_directory('actuator_bringup')) / 'config' / f'{scenario}.yaml'
    if not path.is_file():
        names = sorted(p.stem for p in path.parent.glob('*.yaml'))
        raise SystemExit(f'bringup: no scenario {scenario!r}; installed: {", ".join(names)}')
    return path


def scenario_duration(scenario: str) -> float:
    """Return the paper scenario's run length [s] (10 s for any other parameter file)."""
    known = all_scenarios().get(scenario)
    return known.duration_s if known is not None else 10.0


@dataclass
class RunResult:
    """What a bring-up produced."""

    name: str
    mode: str
    bag: Optional[Path]
    run_dir: Path
    timing_log: Path
    exit_codes: dict
    cpu_percent: dict
    peak_rss_mb: dict
    wall_s: float


class _Stopped(Exception):
    """SIGTERM (or SIGINT) reached the runner."""


def _raise_stopped(*_) -> None:
    raise _Stopped()


def run_closed_loop(
    scenario: str,
    mode: str,
    duration_s: float | None = None,
    record: bool = True,
    bag_root: Path = Path('bags'),
    results_root: Path = Path('results/runs'),
    executor: str = 'events',
    extra_params: Sequence[str] = (),
    quiet: bool = False,
    thread_priority: int = 0,
    cpus: dict | None = None,
    joint: str = 'plant',
    joint_parameters: dict | None = None,
    composed: bool = False,
    live_view: bool = False,
    live_view_parameters: dict | None = None,
    diagnostics_rate_hz: float | None = None,
    joints: int = 1,
    record_in_process: bool = False,
    joint_params_files: Sequence[Path] = (),
) -> RunResult:
    """Start the nodes of ``scenario`` in ``mode``, run to the end, stop everything.

    Return the result. ``duration_s`` None runs the scenario's own length (10 s for the paper's
    cases), never forever. ``thread_priority`` > 0: SCHED_FIFO for the ESO and controller, one
    level above for the joint (graph.closed_loop). ``cpus`` pins by key ('joint', 'eso',
    'controller'). ``composed``: the joint, ESO and controller in one process
    (composition.compose).
    ``diagnostics_rate_hz``: controller/state and plant/truth; ``joints``: CiA 402 drives on
    one bus, each loop under its namespace (graph.closed_loop). ``record_in_process``: the
    composed loop's process writes the bag itself (composition.compose). ``joint_params_files``:
    parameter files for the joint's process (plant or driver), loaded after the scenario's.
    """
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
    if bag is not None:
        bag_root.mkdir(parents=True, exist_ok=True)
    specs = closed_loop(
        mode,
        duration_s,
        record=record,
        bag=bag,
        joint=joint,
        thread_priority=thread_priority,
        cpus=cpus,
        executor=executor,
        logs=run_dir,
        joint_parameters=joint_parameters,
        live_view=live_view,
        live_view_parameters=live_view_parameters,
        diagnostics_rate_hz=diagnostics_rate_hz,
        joints=joints,
    )
    if composed:
        specs = compose(specs, record_in_process)
    procs: dict[str, RosProcess] = {}
    figures: dict[str, ProcessFigures] = {}
    previous = {s: signal.signal(s, _raise_stopped) for s in (signal.SIGTERM, signal.SIGINT)}
    start = time.monotonic()
    codes: dict = {}
    try:
        for spec in specs:
            extra = _extra_arguments(spec, extra_params) + _joint_arguments(
                spec, joint_params_files
            )
            args = ros_arguments(spec, params, run_dir)
            procs[spec.key] = RosProcess.installed(
                spec.package, spec.executable, args + extra, log_dir=run_dir, name=spec.key
            )
            figures[spec.key] = ProcessFigures(procs[spec.key].pid)
        if not quiet:
            print(
                f'[bringup] {scenario} in {mode} mode: {", ".join(procs)} started; '
                f'logs in {run_dir}',
                flush=True,
            )
        leaders = [s.key for s in specs if s.leader]
        wait_for_leader(procs, figures, duration_s, quiet, leaders)
    except _Stopped:
        print('[bringup] stopped by a signal: stopping every node', file=sys.stderr, flush=True)
        codes['bringup'] = 130
    finally:
        for key, proc in reversed(list(procs.items())):
            figures[key].sample()
            codes[key] = proc.stop()
        for s, handler in previous.items():
            signal.signal(s, handler)
    wall = time.monotonic() - start
    return RunResult(
        name,
        mode,
        bag,
        run_dir,
        run_dir / 'controller_timing.npz',
        codes,
        {k: f.cpu_percent() for k, f in figures.items()},
        {k: f.peak_rss_mb for k, f in figures.items()},
        wall,
    )


def _extra_arguments(spec, extra_params: Sequence[str]) -> list[str]:
    """``extra_params`` (ROS arguments for the ESO and the controller) of one process."""
    if node_kind(spec) in ('controller', 'eso'):
        return list(extra_params)
    targets = [m.name for m in spec.members if node_kind(m) in ('controller', 'eso')]
    if not targets:  # the joint, the drive, the recorder: none of them
        return []
    out, it = [], iter(extra_params)
    for arg in it:  # in a container each '-p name:=value' is aimed at the ESO and controller
        if arg in ('-p', '--param'):
            value = next(it, '')
            for target in targets:
                out += [arg, f'{target}:{value}']
        else:
            out.append(arg)
    return out


def _joint_arguments(spec, files: Sequence[Path]) -> list[str]:
    """``--params-file`` of each joint parameter file, for the process that holds the joint."""
    kinds = {node_kind(spec), *(node_kind(m) for m in spec.members)}
    if not kinds & {'plant', 'driver'}:
        return []
    return [a for f in files for a in ('--params-file', str(Path(f).resolve()))]


def run_launched(
    scenario: str,
    mode: str,
    duration_s: float,
    bag_root: Path,
    results_root: Path,
    thread_priority: int = 0,
    diagnostics_rate_hz: float | None = None,
    record: bool = True,
) -> RunResult:
    """Make the same run through ``ros2 launch`` (closed_loop.launch.py), where it is installed.

    For the benchmark's launched variant: the launch file builds the processes from the same
    description (graph.closed_loop) and drives their lifecycle; CPU and memory are read from
    the node processes launch starts.
    """
    stamp = dt.datetime.now(dt.timezone.utc).strftime('%Y%m%dT%H%M%SZ')
    name = f'{scenario}_{mode}_launch_{stamp}'
    run_dir, bag = results_root / name, bag_root / name
    run_dir.mkdir(parents=True, exist_ok=True)
    bag_root.mkdir(parents=True, exist_ok=True)
    cmd = [
        'ros2',
        'launch',
        'actuator_bringup',
        'closed_loop.launch.py',
        f'scenario:={scenario}',
        f'mode:={mode}',
        f'duration:={duration_s}',
        f'thread_priority:={thread_priority}',
        f'bag:={bag}',
        f'logs:={run_dir}',
        f'record:={"true" if record else "false"}',
    ]
    if diagnostics_rate_hz is not None:
        cmd.append(f'diagnostics_rate_hz:={diagnostics_rate_hz}')
    start = time.monotonic()
    launch = RosProcess(cmd, log_dir=run_dir, name='launch')
    figures: dict[str, ProcessFigures] = {}
    names = {
        'plant_node': 'plant',
        'eso_node': 'eso',
        'controller_node': 'controller',
        'recorder': 'recorder',
    }
    marked = False
    deadline = start + max(120.0, 30.0 * duration_s)
    try:
        while launch.running and time.monotonic() < deadline:
            for child in ProcessFigures(launch.pid).children():
                key = names.get(Path(child.cmdline()[1] if len(child.cmdline()) > 1 else '').name)
                if key and key not in figures:
                    figures[key] = ProcessFigures(child.pid)
            for f in figures.values():
                f.sample()
            if not marked and 'sampling started' in launch.output:
                for f in figures.values():
                    f.mark()
                marked = True
            time.sleep(0.2)
    finally:
        code = launch.stop()
    return RunResult(
        name,
        mode,
        bag,
        run_dir,
        run_dir / 'controller_timing.npz',
        {'launch': code},
        {k: f.cpu_percent() for k, f in figures.items()},
        {k: f.peak_rss_mb for k, f in figures.items()},
        time.monotonic() - start,
    )


def wait_for_leader(
    procs: dict[str, RosProcess],
    figures: dict[str, ProcessFigures],
    duration_s: float | None,
    quiet: bool,
    leaders: Sequence[str],
) -> None:
    """Poll until a leader (a joint) exits at the end of the run (none: for ``duration_s``).

    Mark CPU baselines once every leader logged 'sampling started'. Without a leader
    (``--joint none``: the driver runs elsewhere) the run is the nodes' for ``duration_s`` of
    wall time. With several joints the run ends when the first of them ends it.
    """
    marked = False
    deadline = time.monotonic() + (max(120.0, 30.0 * duration_s) if duration_s else float('inf'))
    last_note = started = time.monotonic()
    while True:
        if any(not procs[key].running for key in leaders):
            break
        if not leaders and duration_s and time.monotonic() - started >= duration_s:
            break
        for f in figures.values():
            f.sample()
        if not marked and all('sampling started' in procs[key].output for key in leaders):
            for f in figures.values():
                f.mark()
            marked = True
        for key, proc in procs.items():
            if key not in leaders and not proc.running:
                raise SystemExit(
                    f'bringup: {key} exited early with code {proc.returncode}; see '
                    f'{proc.stderr_path}'
                )
        if time.monotonic() > deadline:
            raise SystemExit('bringup: the run did not finish in time; see the logs')
        if not quiet and time.monotonic() - last_note > 5.0:
            print(f'[bringup] running ({time.monotonic() - started:.0f} s)', flush=True)
            last_note = time.monotonic()
        time.sleep(0.2)


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: one closed-loop run of a scenario, optionally recorded to bags/."""
    parser = argparse.ArgumentParser(prog='bringup', description=__doc__.splitlines()[0])
    parser.add_argument(
        '--scenario',
        default=None,
        help='installed scenario (share/actuator_bringup/config/<name>.yaml; default: '
        "case2_pp_nftsmc_eso for the plant, drive_pp_nftsmc_eso, tuned for the drive's delay, "
        'for a CiA 402 joint)',
    )
    parser.add_argument('--mode', choices=MODES, default='realtime')
    parser.add_argument(
        '--duration',
        type=float,
        default=None,
        help="run length [s] (default: the paper scenario's, 10 s)",
    )
    parser.add_argument(
        '--joint',
        choices=JOINTS,
        default='plant',
        help='plant (simulated joint), cia402_sim (CANopen driver + simulated drive), cia402 '
        '(driver on a real bus), none (a driver started elsewhere)',
    )
    parser.add_argument('--no-record', action='store_true', help='do not start the recorder')
    parser.add_argument(
        '--bags', type=Path, default=Path('bags'), help='folder for bags (default bags/)'
    )
    parser.add_argument('--executor', choices=('events', 'single_threaded'), default='events')
    parser.add_argument(
        '--thread-priority',
        type=int,
        default=0,
        metavar='N',
        help='SCHED_FIFO priority of the ESO and controller, the joint one above (0 = normal)',
    )
    parser.add_argument(
        '--composed',
        action='store_true',
        help='run the joint, the ESO and the controller in one process on one executor',
    )
    parser.add_argument(
        '--record-in-process',
        action='store_true',
        help="with --composed in sim mode: the loop's process writes the bag itself, no "
        'recorder process (a faster lockstep; records only what its nodes publish)',
    )
    parser.add_argument(
        '--pin',
        action='store_true',
        help='pin the joint to CPU 0 and the ESO and controller (which run in sequence) to CPU '
        "1; with --composed the loop's process on CPU 0 (graph.PINNING)",
    )
    parser.add_argument(
        '--params-file',
        type=Path,
        action='append',
        default=[],
        metavar='YAML',
        help='a ROS 2 parameter file for the ESO and the controller, loaded after the '
        "scenario's (e.g. share/actuator_studies/config/pp_nftsmc_eso_designed.yaml); repeatable",
    )
    parser.add_argument(
        '--joint-params-file',
        type=Path,
        action='append',
        default=[],
        metavar='YAML',
        help='a ROS 2 parameter file for the joint (plant or driver), loaded after the '
        "scenario's: e.g. a simulated joint's parameters (actuator_plant: nominal.*, seal.*, "
        'encoder.*); repeatable',
    )
    parser.add_argument(
        '--live-view',
        action='store_true',
        help='also serve the loop to Foxglove (live_view on ws://127.0.0.1:8765; README)',
    )
    parser.add_argument(
        '--diagnostics-rate',
        type=float,
        default=None,
        metavar='HZ',
        help='rate of controller/state and plant/truth (0: every sample; default: every sample '
        f'when recording or in sim, {LIVE_DIAGNOSTICS_RATE_HZ:g} Hz otherwise)',
    )
    parser.add_argument(
        '--joints',
        type=int,
        default=1,
        metavar='N',
        help=f'CiA 402 drives on one bus (1-{MAX_JOINTS_ON_BUS}; with --joint cia402_sim or '
        'cia402): node ids 1..N, each with its driver, ESO and controller under /joint<i>',
    )
    args = parser.parse_args(argv)
    if not 1 <= args.joints <= MAX_JOINTS_ON_BUS:
        parser.error(f'--joints must be in [1, {MAX_JOINTS_ON_BUS}]')
    if args.joints > 1 and args.joint not in ('cia402_sim', 'cia402'):
        parser.error('--joints above 1 needs --joint cia402_sim or cia402 (drives on one bus)')
    low, high = limits.DIAGNOSTICS_RATE_RANGE_HZ
    if args.diagnostics_rate is not None and not low <= args.diagnostics_rate <= high:
        parser.error(f'--diagnostics-rate must be in [{low:g}, {high:g}] Hz')
    if args.duration is not None and not 0.0 < args.duration <= 3600.0:
        parser.error('--duration must be in (0, 3600] s')
    if not 0 <= args.thread_priority <= 99:
        parser.error('--thread-priority must be in [0, 99]')
    if args.record_in_process and not (args.composed and args.mode == 'sim'):
        parser.error('--record-in-process needs --composed and --mode sim (composition.compose)')
    if args.record_in_process and args.no_record:
        parser.error('--record-in-process records the run: not with --no-record')
    if args.joint in ('cia402_sim', 'cia402') and args.thread_priority == 0:
        print(
            '[bringup] warning: the loop through the CiA 402 driver keeps its 1 kHz SYNC grid '
            'only under SCHED_FIFO (--thread-priority 50); with normal scheduling on 2 cores it '
            'ran away to the joint soft limit (README "CiA 402 drive")',
            file=sys.stderr,
            flush=True,
        )
    for option, paths in (
        ('--params-file', args.params_file),
        ('--joint-params-file', args.joint_params_file),
    ):
        for path in paths:
            if not path.is_file():
                parser.error(f'{option} {path}: no such file')
    if args.scenario is None:
        args.scenario = default_scenario(args.joint)
    duration = args.duration if args.duration is not None else scenario_duration(args.scenario)
    result = run_closed_loop(
        args.scenario,
        args.mode,
        duration,
        not args.no_record,
        args.bags,
        executor=args.executor,
        thread_priority=args.thread_priority,
        extra_params=[a for f in args.params_file for a in ('--params-file', str(f.resolve()))],
        cpus=PINNING if args.pin else None,
        joint=args.joint,
        composed=args.composed,
        live_view=args.live_view,
        diagnostics_rate_hz=args.diagnostics_rate,
        joints=args.joints,
        record_in_process=args.record_in_process,
        joint_params_files=args.joint_params_file,
    )
    print(
        json.dumps(
            {
                'bag': str(result.bag),
                'exit_codes': result.exit_codes,
                'cpu_percent': result.cpu_percent,
                'peak_rss_mb': result.peak_rss_mb,
            },
            indent=1,
        )
    )
    # A stop by SIGINT/SIGTERM is a clean end (exit 0) when every node then ended cleanly; the
    # JSON keeps 'bringup': 130 to say the run was cut short.
    nodes = {k: v for k, v in result.exit_codes.items() if k != 'bringup'}
    return 0 if all(code == 0 for code in nodes.values()) else 1


if __name__ == '__main__':
    sys.exit(main())
