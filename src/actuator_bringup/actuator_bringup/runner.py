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
import json
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

from ament_index_python.packages import get_package_share_directory

from actuator_bringup.composition import compose
from actuator_bringup.gain_check import UnstableGains, check_gains
from actuator_bringup.ros_arguments import ros_arguments
from actuator_bringup.run_description import (
    PINNING,
    NodeSpec,
    closed_loop,
    default_scenario,
    node_kind,
    run_name,
)
from actuator_bringup.run_options import (
    MODES,
    RUN_OPTIONS,
    OptionError,
    check_parameter_files,
    joint_overrides,
    node_names,
    parse,
)
from actuator_bringup.supervisor import ProcessFigures, RosProcess
from actuator_sim.params_yaml import all_scenarios


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
    params_files: Sequence[Path] = (),
    allow_unstable_gains: bool = False,
) -> RunResult:
    """Start the nodes of ``scenario`` in ``mode``, run to the end, stop everything.

    Return the result. ``duration_s`` None runs the scenario's own length (10 s for the paper's
    cases), never forever. ``thread_priority`` > 0: SCHED_FIFO for the ESO and controller, one
    level above for the joint (graph.closed_loop). ``cpus`` pins by key ('joint', 'eso',
    'controller'). ``composed``: the joint, ESO and controller in one process
    (composition.compose).
    ``diagnostics_rate_hz``: controller/state and plant/truth; ``joints``: CiA 402 drives on
    one bus, each loop under its namespace (graph.closed_loop). ``record_in_process``: the
    composed loop's process writes the bag itself (composition.compose). ``params_files``: ROS 2
    parameter files every node process loads after the scenario's, each section for a node of
    this run (run_options.check_parameter_files; refused with one line otherwise). The gains
    they name are judged at the joint's delay first (gain_check): an unstable set is refused
    unless ``allow_unstable_gains``.
    """
    if duration_s is None:
        duration_s = scenario_duration(scenario)
    if mode not in MODES:
        raise SystemExit(f'bringup: mode must be one of {", ".join(MODES)}')
    params = scenario_file(scenario)
    name = run_name(scenario, mode)
    run_dir = results_root / name
    bag = bag_root / name if record else None
    try:
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
    except ValueError as exc:  # a joint's parameters refused before start (launch_spec)
        raise SystemExit(f'bringup: {exc}') from None
    if composed:
        specs = compose(specs, record_in_process)
    try:
        check_parameter_files(tuple(params_files), node_names(specs))
    except OptionError as exc:
        raise SystemExit(f'bringup: {exc}') from None
    files = [Path(f).resolve() for f in params_files]
    _judge_gains(scenario, [params, *files], joint, allow_unstable_gains)
    run_dir.mkdir(parents=True, exist_ok=True)  # nothing is made for a run refused above
    if bag is not None:
        bag_root.mkdir(parents=True, exist_ok=True)
    procs: dict[str, RosProcess] = {}
    figures: dict[str, ProcessFigures] = {}
    previous = {s: signal.signal(s, _raise_stopped) for s in (signal.SIGTERM, signal.SIGINT)}
    start = time.monotonic()
    codes: dict = {}
    try:
        _start(specs, extra_params, params, run_dir, files, procs, figures)
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
    return _run_result(name, mode, bag, run_dir, codes, figures, wall)


def _judge_gains(
    scenario: str, files: Sequence[Path], joint: str, allow_unstable_gains: bool
) -> None:
    """Refuse gains unstable at the joint's delay (one line); print a warning the check gives."""
    try:
        _, warning = check_gains(scenario, files, joint, allow_unstable_gains)
    except UnstableGains as exc:
        raise SystemExit(f'bringup: {exc}') from None
    if warning:
        print(f'[bringup] warning: {warning}', file=sys.stderr, flush=True)


def _start(
    specs: Sequence[NodeSpec],
    extra_params: Sequence[str],
    params: Path,
    run_dir: Path,
    files: Sequence[Path],
    procs: dict[str, RosProcess],
    figures: dict[str, ProcessFigures],
) -> None:
    """Start each spec's process in order, adding it to ``procs`` and ``figures`` as it starts."""
    for spec in specs:
        extra = _extra_arguments(spec, extra_params)
        args = ros_arguments(spec, params, run_dir, files)
        procs[spec.key] = RosProcess.installed(
            spec.package, spec.executable, args + extra, log_dir=run_dir, name=spec.key
        )
        figures[spec.key] = ProcessFigures(procs[spec.key].pid)


def _run_result(
    name: str,
    mode: str,
    bag: Optional[Path],
    run_dir: Path,
    exit_codes: dict,
    figures: dict[str, ProcessFigures],
    wall_s: float,
) -> RunResult:
    """Return a run's result, with each process' CPU use and peak memory from its figures."""
    return RunResult(
        name,
        mode,
        bag,
        run_dir,
        run_dir / 'controller_timing.npz',
        exit_codes,
        {k: f.cpu_percent() for k, f in figures.items()},
        {k: f.peak_rss_mb for k, f in figures.items()},
        wall_s,
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
    name = run_name(scenario, f'{mode}_launch')
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
    return _run_result(
        name, mode, bag, run_dir, {'launch': code}, figures, time.monotonic() - start
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
                    f'bringup: {key} exited early with code {proc.returncode}'
                    + _said(proc.stderr_path)
                )
        if time.monotonic() > deadline:
            raise SystemExit('bringup: the run did not finish in time; see the logs')
        if not quiet and time.monotonic() - last_note > 5.0:
            print(f'[bringup] running ({time.monotonic() - started:.0f} s)', flush=True)
            last_note = time.monotonic()
        time.sleep(0.2)


def build_parser() -> argparse.ArgumentParser:
    """Return the runner's command line, built from the run's options (RUN_OPTIONS)."""
    parser = argparse.ArgumentParser(prog='bringup', description=__doc__.splitlines()[0])
    for option in RUN_OPTIONS:
        if not option.runner:
            continue
        help_text = f'{option.description} ({option.range_text()})'
        if option.kind is bool:
            action = 'store_false' if option.default else 'store_true'
            what = option.flag_help or option.description
            parser.add_argument(option.cli, action=action, help=what, dest=option.name)
        elif option.kind is list:
            parser.add_argument(
                option.cli,
                action='append',
                default=[],
                metavar='PATH',
                help=help_text,
                dest=option.name,
            )
        else:
            parser.add_argument(
                option.cli,
                default=None,
                metavar=option.unit.upper() or option.name.split('_')[-1].upper(),
                help=help_text,
                dest=option.name,
            )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: one closed-loop run of a scenario, optionally recorded to bags/."""
    parser = build_parser()
    raw = vars(parser.parse_args(argv))
    try:
        args = {
            o.name: o.default if raw[o.name] is None else parse(o, raw[o.name], o.cli)
            for o in RUN_OPTIONS
            if o.runner
        }
        joint_parameters = joint_overrides(
            args['joint'], args['eds_file'], [Path(f) for f in args['params_file']]
        )
    except OptionError as exc:  # named as the launch file names it; here as the user typed it
        problem = str(exc)
        for option in RUN_OPTIONS:
            if option.runner and problem.startswith(f'{option.name} '):
                problem = option.cli + problem[len(option.name) :]
        parser.error(problem)
    if args['joints'] > 1 and args['joint'] not in ('cia402_sim', 'cia402'):
        parser.error('--joints above 1 needs --joint cia402_sim or cia402 (drives on one bus)')
    if args['record_in_process'] and not (args['composed'] and args['mode'] == 'sim'):
        parser.error('--record-in-process needs --composed and --mode sim (composition.compose)')
    if args['record_in_process'] and not args['record']:
        parser.error('--record-in-process records the run: not with --no-record')
    if args['joint'] in ('cia402_sim', 'cia402') and args['thread_priority'] == 0:
        print(
            '[bringup] warning: the loop through the CiA 402 driver keeps its 1 kHz SYNC grid '
            'only under SCHED_FIFO (--thread-priority 50); with normal scheduling on 2 cores it '
            'ran away to the joint soft limit (docs/cia402.md)',
            file=sys.stderr,
            flush=True,
        )
    scenario = args['scenario'] or default_scenario(args['joint'])
    duration = args['duration'] or scenario_duration(scenario)
    rate = args['diagnostics_rate_hz']
    result = run_closed_loop(
        scenario,
        args['mode'],
        duration,
        args['record'],
        Path(args['bags']),
        executor=args['executor'],
        thread_priority=args['thread_priority'],
        params_files=[Path(f) for f in args['params_file']],
        cpus=PINNING if args['pin'] else None,
        joint=args['joint'],
        joint_parameters=joint_parameters,
        composed=args['composed'],
        live_view=args['live_view'],
        diagnostics_rate_hz=None if rate != rate else rate,
        joints=args['joints'],
        record_in_process=args['record_in_process'],
        allow_unstable_gains=args['allow_unstable_gains'],
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
    for key, code in nodes.items():
        if code != 0:
            said = _said(result.run_dir / f'{key}.stderr')
            print(f'bringup: {key} exited with code {code}{said}', file=sys.stderr)
    return 0 if all(code == 0 for code in nodes.values()) else 1


def _said(stderr_path: Path) -> str:
    """Return ': <the last line the process wrote to stderr> (its log: <path>)'."""
    text = stderr_path.read_text(errors='replace') if stderr_path.exists() else ''
    last = next((x.strip() for x in reversed(text.splitlines()) if x.strip()), '')
    return (f': {last}' if last else '') + f' (its log: {stderr_path})'


if __name__ == '__main__':
    sys.exit(main())
