# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The driver's parameters and the simulated drive's process, for the launch file and the runner.

    from actuator_cia402.launch_spec import driver_parameters, sim_drive_command, free_port
    port = free_port()
    params = driver_parameters(simulated=True, hub_port=port, stop_after_s=10.0)
    drive = sim_drive_command(port, working_condition='deep_sea')
    # launch / runner: SIM_DRIVE_PACKAGE/SIM_DRIVE_EXECUTABLE with ``drive`` as arguments, then
    # Node(package=DRIVER_PACKAGE, executable=DRIVER_EXECUTABLE, name=DRIVER_NODE_NAME,
    #      parameters=[params]) in place of actuator_plant's plant_node

ROS-free. The scenario YAMLs' plant-only parameters belong to node name actuator_plant and do
not reach the driver; its sample time is sync_period_s, which must equal the scenario's.
"""

from __future__ import annotations

import dataclasses
import socket
from typing import Any, Sequence

from actuator_cia402.config import DriverParameters, check_real_drive
from actuator_cia402.hub import LOOPBACK
from actuator_cia402.sim_settings import SimDriveSettings
from actuator_core import limits

DRIVER_PACKAGE = 'actuator_cia402'
DRIVER_EXECUTABLE = 'cia402_driver'
DRIVER_NODE_NAME = 'actuator_cia402_driver'
SIM_DRIVE_PACKAGE = 'actuator_cia402'
SIM_DRIVE_EXECUTABLE = 'cia402_sim_drive'


def free_port() -> int:
    """Return a TCP port on 127.0.0.1 free now (the simulated bus's hub binds it next)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((LOOPBACK, 0))
        return sock.getsockname()[1]


def driver_parameters(
    simulated: bool,
    hub_port: int = 0,
    channel: str | None = None,
    node_id: int = 1,
    bitrate: int = 1_000_000,
    sample_time_s: float = limits.SAMPLE_TIME_S,
    stop_after_s: float = 0.0,
    wait_for_subscribers: int = 0,
    autostart: bool = True,
    **overrides: Any,
) -> dict[str, Any]:
    """Flat ROS parameters of the driver node for a closed-loop run (checked: ValueError).

    ``simulated``: the drive is ``cia402_sim_drive`` serving its hub on 127.0.0.1:``hub_port``;
    otherwise socketcan on ``channel`` (default can0), and ``eds_file`` must be given.
    ``overrides`` are further parameters by their ROS names (the drive's, or the joint node's).
    """
    interface = 'hub' if simulated else 'socketcan'
    if channel is None:
        channel = f'{LOOPBACK}:{hub_port}' if simulated else 'can0'
    params: dict[str, Any] = {
        'node_id': node_id,
        'interface': interface,
        'channel': channel,
        'bitrate': bitrate,
        'sample_time_s': sample_time_s,
        'simulated_drive': simulated,
        'autostart': autostart,
        'mode': 'realtime',
        'stop_after_s': stop_after_s,
        'wait_for_subscribers': wait_for_subscribers,
    }
    params.update(overrides)
    _check(params)
    return params


def sim_drive_command(
    port: int,
    node_ids: Sequence[int] = (1,),
    sync_period_s: float = limits.SAMPLE_TIME_S,
    thread_priority: int = 0,
    **sim: Any,
) -> list[str]:
    """Arguments of ``cia402_sim_drive`` for ``port`` and drives ``node_ids`` (checked).

    ``thread_priority``: SCHED_FIFO of the drive process (0 = normal). ``sim`` are
    SimDriveSettings by their names, with or without the 'sim.' prefix.
    """
    settings = SimDriveSettings(**{k.removeprefix('sim.'): v for k, v in sim.items()})
    args = ['--port', str(port), '--sync-period', repr(sync_period_s)]
    if thread_priority:
        args += ['--thread-priority', str(thread_priority)]
    for node_id in node_ids:
        args += ['--node-id', str(node_id)]
    return args + settings.arguments()


#: Parameters of the node besides the drive's and the joint node's common settings.
NODE_PARAMETERS = {
    'use_sim_time',
    'autostart',
    'mode',
    'timing_log',
    'allow_unknown_parameters',
    'thread_priority',
    'cpu_affinity',
    'executor',
}


def _names() -> tuple[set[str], set[str]]:
    """Return (the drive's parameter names, the joint node's common ones)."""
    from actuator_core.joint import JointSettings

    drive_names = {f.name for f in dataclasses.fields(DriverParameters)} - {
        'sync_period_s',
        'current_limit_a',
    }
    return drive_names, {f.name for f in dataclasses.fields(JointSettings)}


def known_names() -> set[str]:
    """Return every parameter name the driver node declares (its drive's, common, node's)."""
    drive_names, common_names = _names()
    return drive_names | common_names | NODE_PARAMETERS


def _check(params: dict[str, Any]) -> None:
    """Build DriverParameters and JointSettings from the flat names, so a refusal fails here."""
    from actuator_core.joint import JointSettings

    drive_names, common_names = _names()
    unknown = sorted(set(params) - drive_names - common_names - NODE_PARAMETERS)
    if unknown:
        raise ValueError(f'unknown driver parameter(s): {", ".join(unknown)}')
    if params.get('mode', 'realtime') != 'realtime':
        raise ValueError("mode = 'sim' refused: the CiA 402 driver runs in real time only")
    common = JointSettings(**{k: v for k, v in params.items() if k in common_names})
    drive = DriverParameters(
        **{k: v for k, v in params.items() if k in drive_names},
        sync_period_s=common.sample_time_s,
        current_limit_a=common.current_limit_a,
    )
    drive.eds_path()
    check_real_drive(drive, (common.position_min_rad, common.position_max_rad))


def driver_arguments(params: dict[str, Any]) -> list[str]:
    """Return the parameters as command-line arguments of the installed executable."""
    args = ['--ros-args']
    for key, value in params.items():
        text = ('true' if value else 'false') if isinstance(value, bool) else str(value)
        args += ['-p', f'{key}:={text}']
    return args
