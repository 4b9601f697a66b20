# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Launch file of one closed-loop run.

    ros2 launch actuator_bringup closed_loop.launch.py [scenario:=...] [mode:=realtime|sim]
        [duration:=S] [params_file:=FILE[,FILE]] [eds_file:=FILE] ...

One closed-loop run: the joint (simulated plant, or the CiA 402 driver), the ESO, the controller
and the recorder as separate processes, built from
``actuator_bringup.run_description.closed_loop``, the same description the ``bringup`` runner
uses; the launch arguments are the run's options (``actuator_bringup.run_options.RUN_OPTIONS``),
the runner's flags under their launch names, read back and refused in one line the same way. The
managed nodes configure and activate themselves (``autostart:=true``, the default): a node whose
transition event launch missed would otherwise never be activated (ros2/rcl#1166), and a sim
lockstep then waited for a command that never came. ``autostart:=false`` leaves them unconfigured
for ``ros2 lifecycle set`` or a lifecycle manager. The run ends when the joint process ends
(``duration`` elapsed, or it failed): every other process is then stopped with SIGINT and the
joint's exit code is reported; ``ros2 launch`` exits 1 when a joint exited non-zero.
``composed:=true`` runs the joint, the ESO and the controller in one process (actuator_bringup
loop_container, composition.compose); ``ros2 lifecycle`` still reaches each by its name.
``pin:=true`` pins the processes as ``bringup --pin`` does.
"""

import os
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import (
    DeclareLaunchArgument,
    EmitEvent,
    LogInfo,
    OpaqueFunction,
    RegisterEventHandler,
)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown, matches_action
from launch.events.process import ShutdownProcess
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode, Node

from actuator_bringup.composition import compose
from actuator_bringup.gain_check import UnstableGains, check_gains
from actuator_bringup.ros_arguments import ros_arguments
from actuator_bringup.run_description import (
    PINNING,
    closed_loop,
    default_scenario,
    run_name,
)
from actuator_bringup.run_options import (
    RUN_OPTIONS,
    OptionError,
    check_parameter_files,
    default_for,
    joint_overrides,
    node_names,
    parse,
)
from actuator_sim.params_yaml import node_parameters


def _options(context) -> dict:
    """Return every launch argument's typed value (run_options.parse: one line when refused)."""
    values = {}
    for option in RUN_OPTIONS:
        if option.launch:
            text = LaunchConfiguration(option.name).perform(context)
            try:
                values[option.name] = parse(option, text)
            except OptionError as exc:
                raise RuntimeError(str(exc)) from None
    return values


def _leader_exits(leaders, producer=None, drive=None):
    """OnProcessExit of the joints: the first to end ends the run, in the runner's stop order.

    Every process but the SYNC producer and the simulated drive gets SIGINT at once; the
    producer once every other joint has ended (no consumer loses its SYNC), and launch's
    Shutdown (the drive last, as hardware) once every joint has ended; where a joint exited
    non-zero, an action that raises instead, which shuts launch down the same way and makes
    ``ros2 launch`` exit 1 (its exit code says only whether an action raised). Nothing on Ctrl-C
    (launch is ending already).
    """
    ended = []
    failed = []

    def fail(context):
        raise RuntimeError(f'the run failed: {"; ".join(failed)}')

    def on_exit(event, context):
        if context.is_shutdown:
            return None
        ended.append(event.action)
        code = event.returncode
        if code != 0:
            failed.append(f'{event.action.name} exited with code {code}')
        actions = []
        if len(ended) == 1:
            text = f'{event.action.name} exited with code {code}: ending the run'
            held = (producer, drive)
            actions += [
                LogInfo(msg=text if code == 0 else f'ERROR: {text}'),
                EmitEvent(event=ShutdownProcess(process_matcher=lambda a: a not in held)),
            ]
        if producer is not None and producer not in ended and len(ended) == len(leaders) - 1:
            actions.append(
                EmitEvent(event=ShutdownProcess(process_matcher=matches_action(producer)))
            )
        if len(ended) == len(leaders):  # a raising action shuts launch down by itself
            reason = 'every joint ended: ending the run'
            ending = (
                OpaqueFunction(function=fail)
                if failed
                else EmitEvent(event=Shutdown(reason=reason))
            )
            actions.append(ending)
        return actions

    return on_exit


def _processes(context):
    options = _options(context)
    joint = options['joint']
    scenario = options['scenario'] or default_scenario(joint)  # the drive's is tuned for it
    params = os.path.join(
        get_package_share_directory('actuator_bringup'), 'config', f'{scenario}.yaml'
    )
    if not os.path.isfile(params):
        raise RuntimeError(f'no scenario {scenario!r}: {params} does not exist')
    rate = options['diagnostics_rate_hz']
    try:
        joint_parameters = joint_overrides(
            joint, options['eds_file'], [Path(f).resolve() for f in options['params_file']]
        )
        specs = closed_loop(
            options['mode'],
            options['duration'],
            record=options['record'],
            bag=options['bag'] or Path('bags') / run_name(scenario, options['mode']),
            joint=joint,
            thread_priority=options['thread_priority'],
            cpus=PINNING if options['pin'] else None,
            executor=options['executor'],
            logs=Path(options['logs']) if options['logs'] else None,
            joint_parameters=joint_parameters,
            autostart=options['autostart'],
            live_view=options['live_view'],
            diagnostics_rate_hz=None if rate != rate else rate,
            joints=options['joints'],
        )
    except (OptionError, ValueError) as exc:
        raise RuntimeError(str(exc)) from None
    if options['composed']:
        specs = compose(specs, options['record_in_process'])
    elif options['record_in_process']:
        raise RuntimeError('record_in_process:=true needs composed:=true (and mode:=sim)')
    files = [Path(f).resolve() for f in options['params_file']]
    try:
        check_parameter_files(tuple(files), node_names(specs))
        _, warning = check_gains(
            scenario, [Path(params), *files], joint, options['allow_unstable_gains']
        )
    except (OptionError, UnstableGains) as exc:
        raise RuntimeError(str(exc)) from None
    warnings = [LogInfo(msg=f'WARNING: {warning}')] if warning else []
    actions, leaders, producer, drive = warnings, [], None, None
    for spec in specs:
        if spec.arguments:  # a plain process (the simulated drive): its own command line
            drive = Node(
                package=spec.package,
                executable=spec.executable,
                arguments=list(spec.arguments),
                output='screen',
            )
            actions.append(drive)
            continue
        if spec.members:  # the container: per-node parameters as node:name:=value
            arguments = ros_arguments(spec, Path(params), params_files=files)
            split = arguments.index('--ros-args')
            action = Node(  # no name=: a __node remap would rename every node of the process
                package=spec.package,
                executable=spec.executable,
                arguments=arguments[:split],
                ros_arguments=arguments[split + 1 :],
                output='screen',
            )
            actions.append(action)
            leaders.append(action)
            if any(m.parameters.get('sync_producer') for m in spec.members):
                producer = action  # several composed CiA 402 joints: the SYNC's container
            continue
        # rcl applies a file's 'actuator_controller:' section to /actuator_controller only: a
        # node in a namespace (several joints) gets its sections as values
        from_file = (
            [node_parameters(Path(params), spec.name) if spec.namespace else params]
            if spec.scenario_file
            else []
        )
        common = dict(
            package=spec.package,
            executable=spec.executable,
            name=spec.name,
            namespace=spec.namespace,
            parameters=from_file + [str(f) for f in files] + [spec.parameters],
            output='screen',
        )
        action = LifecycleNode(**common) if spec.managed else Node(**common)
        actions.append(action)
        if spec.leader:
            leaders.append(action)
            if spec.parameters.get('sync_producer'):
                producer = action
    on_exit = _leader_exits(leaders, producer, drive)
    actions += [
        RegisterEventHandler(OnProcessExit(target_action=leader, on_exit=on_exit))
        for leader in leaders
    ]
    return actions


def generate_launch_description():
    """Launch arguments (the run's options) and the processes of one closed-loop run."""
    arguments = [
        DeclareLaunchArgument(
            option.name,
            default_value=default_for(option),
            description=f'{option.description} ({option.range_text()})',
            **({'choices': list(option.choices)} if option.choices else {}),
        )
        for option in RUN_OPTIONS
        if option.launch
    ]
    return LaunchDescription([*arguments, OpaqueFunction(function=_processes)])
