# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Launch file of one closed-loop run.

    ros2 launch actuator_bringup closed_loop.launch.py [scenario:=...] [mode:=realtime|sim]
        [duration:=S] ...

One closed-loop run: the joint (simulated plant, or the CiA 402 driver), the ESO, the controller
and the recorder as separate processes, built from
``actuator_bringup.run_description.closed_loop``, the same description the ``bringup`` runner uses,
with the same real-time settings (node parameters thread_priority, cpu_affinity, executor). The
managed nodes are driven through configure and activate by launch_ros's lifecycle events. The run
ends when the joint process ends (``duration`` elapsed, or it failed): every other process is then
stopped with SIGINT and the joint's exit code is reported. ``composed:=true`` runs the joint, the
ESO and the controller in one process (actuator_bringup loop_container, composition.compose): the
nodes then configure and activate themselves (autostart), and ``ros2 lifecycle`` still reaches each
by its name. ``pin:=true`` pins the processes as ``bringup --pin`` does (graph.PINNING; a composed
loop on its joint's CPU). Booleans are launch conditions: true/false/1/0, anything else is refused.
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
from launch.conditions import evaluate_condition_expression
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown, matches_action
from launch.events.process import ShutdownProcess
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode, Node
from launch_ros.event_handlers import OnStateTransition
from launch_ros.events.lifecycle import ChangeState
from lifecycle_msgs.msg import Transition

from actuator_sim.params_yaml import node_parameters
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


def _flag(context, name):
    """Return a boolean launch argument through launch's own condition parser."""
    return evaluate_condition_expression(context, [LaunchConfiguration(name)])


def _drive_lifecycle(action):
    """Configure at start, activate once inactive (launch_ros lifecycle events)."""
    configure = EmitEvent(
        event=ChangeState(
            lifecycle_node_matcher=matches_action(action),
            transition_id=Transition.TRANSITION_CONFIGURE,
        )
    )
    activate = RegisterEventHandler(
        OnStateTransition(
            target_lifecycle_node=action,
            goal_state='inactive',
            entities=[
                EmitEvent(
                    event=ChangeState(
                        lifecycle_node_matcher=matches_action(action),
                        transition_id=Transition.TRANSITION_ACTIVATE,
                    )
                )
            ],
        )
    )
    return [activate, configure]


def _leader_exits(leaders, producer=None, drive=None):
    """OnProcessExit of the joints: the first to end ends the run, in the runner's stop order.

    Every process but the SYNC producer and the simulated drive gets SIGINT at once; the
    producer once every other joint has ended (no consumer loses its SYNC), and launch's
    Shutdown (the drive last, as hardware) once every joint has ended. Nothing on Ctrl-C
    (launch is ending already).
    """
    ended = []

    def on_exit(event, context):
        if context.is_shutdown:
            return None
        ended.append(event.action)
        actions = []
        if len(ended) == 1:
            code = event.returncode
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
        if len(ended) == len(leaders):
            actions.append(EmitEvent(event=Shutdown(reason='every joint ended: ending the run')))
        return actions

    return on_exit


def _processes(context):
    scenario = LaunchConfiguration('scenario').perform(context)
    mode = LaunchConfiguration('mode').perform(context)
    joint = LaunchConfiguration('joint').perform(context)
    duration = float(LaunchConfiguration('duration').perform(context))
    priority = int(LaunchConfiguration('thread_priority').perform(context))
    if not _flag(context, 'plant'):
        joint = 'none'
    if not scenario:  # none named: the joint's own (the drive's is tuned for its SYNC delay)
        scenario = default_scenario(joint)
    params = os.path.join(
        get_package_share_directory('actuator_bringup'), 'config', f'{scenario}.yaml'
    )
    if not os.path.isfile(params):
        raise RuntimeError(f'no scenario {scenario!r}: {params} does not exist')
    bag = LaunchConfiguration('bag').perform(context)
    logs = LaunchConfiguration('logs').perform(context)
    composed = _flag(context, 'composed')
    rate = LaunchConfiguration('diagnostics_rate_hz').perform(context)
    joints = int(LaunchConfiguration('joints').perform(context))
    # parameter files for the ESO and the controller after the scenario's (bringup --params-file)
    extra = [f for f in LaunchConfiguration('params_file').perform(context).split(',') if f]
    for path in extra:
        if not os.path.isfile(path):
            raise RuntimeError(f'params_file: {path} does not exist')
    specs = closed_loop(
        mode,
        duration,
        record=_flag(context, 'record'),
        bag=bag or None,
        joint=joint,
        thread_priority=priority,
        cpus=PINNING if _flag(context, 'pin') else None,
        logs=Path(logs) if logs else None,
        autostart=composed,  # launch drives the lifecycle of a node that has a process alone
        live_view=_flag(context, 'live_view'),
        diagnostics_rate_hz=float(rate) if rate else None,
        joints=joints,
    )
    if composed:
        specs = compose(specs, _flag(context, 'record_in_process'))
    elif _flag(context, 'record_in_process'):
        raise RuntimeError('record_in_process:=true needs composed:=true (and mode:=sim)')
    actions, leaders, producer, drive = [], [], None, None
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
            arguments = ros_arguments(spec, Path(params))
            for path in extra:  # rcl applies each file's sections to the nodes they name
                arguments += ['--params-file', path]
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
            parameters=from_file
            + (extra if node_kind(spec) in ('controller', 'eso') else [])
            + [spec.parameters],
            output='screen',
        )
        action = LifecycleNode(**common) if spec.managed else Node(**common)
        actions.append(action)
        if spec.managed:
            actions += _drive_lifecycle(action)
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
    """Launch arguments and the processes of one closed-loop run."""
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                'scenario',
                default_value='',
                description='parameter file share/actuator_bringup/config/<scenario>.yaml; empty: '
                'case2_pp_nftsmc_eso for the plant, drive_pp_nftsmc_eso for a CiA 402 joint',
            ),
            DeclareLaunchArgument(
                'mode',
                default_value='realtime',
                choices=['realtime', 'sim'],
                description="realtime: wall-clock 1 kHz; sim: lockstep on the plant's /clock",
            ),
            DeclareLaunchArgument(
                'duration',
                default_value='0.0',
                description='run length [s] of the whole run; 0 runs until Ctrl-C',
            ),
            DeclareLaunchArgument(
                'joint',
                default_value='plant',
                choices=list(JOINTS),
                description='plant: simulated joint; cia402_sim: CANopen driver and its '
                'simulated drive (a process of its own); cia402: the driver on a real bus; '
                'none: a driver started '
                'elsewhere',
            ),
            DeclareLaunchArgument(
                'plant',
                default_value='true',
                description='false: start no joint (same as joint:=none)',
            ),
            DeclareLaunchArgument(
                'record', default_value='true', description='record all topics to a bag'
            ),
            DeclareLaunchArgument(
                'bag', default_value='', description='bag folder (default bags/<UTC time>)'
            ),
            DeclareLaunchArgument(
                'live_view',
                default_value='false',
                description='also serve the loop to Foxglove (actuator_live_view live_view on '
                'ws://127.0.0.1:8765)',
            ),
            DeclareLaunchArgument(
                'logs',
                default_value='',
                description='folder for the per-node timing files of the benchmark (default none)',
            ),
            DeclareLaunchArgument(
                'composed',
                default_value='false',
                description='true: the joint, ESO and controller in one process on one executor',
            ),
            DeclareLaunchArgument(
                'pin',
                default_value='false',
                description='true: the joint on CPU 0, the ESO and controller on CPU 1; a '
                "composed loop's process on CPU 0 (as bringup --pin)",
            ),
            DeclareLaunchArgument(
                'record_in_process',
                default_value='false',
                description="true (composed:=true, mode:=sim): the loop's process writes the bag "
                'itself, no recorder process (as bringup --record-in-process)',
            ),
            DeclareLaunchArgument(
                'joints',
                default_value='1',
                description=f'CiA 402 drives on one bus (1-{MAX_JOINTS_ON_BUS}; joint:=cia402_sim '
                'or cia402): node ids 1..N, each with its driver, ESO and controller under '
                '/joint<i>',
            ),
            DeclareLaunchArgument(
                'diagnostics_rate_hz',
                default_value='',
                description='rate of controller/state and plant/truth [Hz] (0: every sample; '
                f'empty: every sample when recording or in sim, {LIVE_DIAGNOSTICS_RATE_HZ:g} Hz '
                'otherwise)',
            ),
            DeclareLaunchArgument(
                'params_file',
                default_value='',
                description='parameter files for the ESO and the controller, loaded after the '
                "scenario's, comma-separated (e.g. bag_identify --params FILE; as bringup "
                '--params-file)',
            ),
            DeclareLaunchArgument(
                'thread_priority',
                default_value='0',
                description='SCHED_FIFO priority of the ESO and controller, the joint one above '
                '(0: normal scheduling; the runner and the benchmark use 50)',
            ),
            OpaqueFunction(function=_processes),
        ]
    )
