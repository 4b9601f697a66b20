# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The driver's parameters for a closed-loop run, for the launch file and the runner (ROS-free).

    from actuator_cia402.launch_spec import driver_parameters, DRIVER_PACKAGE, DRIVER_EXECUTABLE
    params = driver_parameters(simulated=True, working_condition='deep_sea', stop_after_s=10.0)
    # launch: Node(package=DRIVER_PACKAGE, executable=DRIVER_EXECUTABLE, name=DRIVER_NODE_NAME,
    #              parameters=[params]) in place of actuator_plant's plant_node
    # runner: driver_arguments(params) -> ['--ros-args', '-p', 'name:=value', ...]

The scenario YAMLs' plant-only parameters belong to node name actuator_plant and do not reach
the driver; its sample time is sync_period_s, which must equal the scenario's sample_time_s.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from actuator_core import limits
from actuator_cia402.config import DriverParameters, SimDriveSettings

DRIVER_PACKAGE = 'actuator_cia402'
DRIVER_EXECUTABLE = 'cia402_driver'
DRIVER_NODE_NAME = 'actuator_cia402_driver'


def driver_parameters(
    simulated: bool,
    working_condition: str = 'deep_sea',
    interface: str | None = None,
    channel: str | None = None,
    node_id: int = 1,
    bitrate: int = 1_000_000,
    sync_period_s: float = limits.SAMPLE_TIME_S,
    stop_after_s: float = 0.0,
    wait_for_subscribers: int = 0,
    autostart: bool = True,
    **overrides: Any,
) -> dict[str, Any]:
    """Flat ROS parameters of the driver for a closed-loop run.

    Checked: raises ValueError when refused.
    ``simulated``: the simulated drive in the driver's process on a virtual bus named after
    the node id (channel default 'sim_joint_<node_id>'); otherwise socketcan on ``channel``
    (default can0). ``overrides`` are further parameters by their ROS names, e.g.
    ``**{'sim.fault_kind': 'over_current', 'sim.fault_at_s': 2.0}``.
    """
    if interface is None:
        interface = 'virtual' if simulated else 'socketcan'
    if channel is None:
        channel = f'sim_joint_{node_id}' if simulated else 'can0'
    params: dict[str, Any] = {
        'node_id': node_id,
        'interface': interface,
        'channel': channel,
        'bitrate': bitrate,
        'sync_period_s': sync_period_s,
        'simulated_drive': simulated,
        'autostart': autostart,
        'stop_after_s': stop_after_s,
        'wait_for_subscribers': wait_for_subscribers,
    }
    if simulated:
        params['sim.working_condition'] = working_condition
    params.update(overrides)
    _check(params)
    return params


def _check(params: dict[str, Any]) -> None:
    """Build DriverParameters from the flat names.

    So a refused value fails here and not in the node.
    """
    sim = {k[4:]: v for k, v in params.items() if k.startswith('sim.')}
    top = {k: v for k, v in params.items() if not k.startswith('sim.')}
    known = {f.name for f in dataclasses.fields(DriverParameters)} | {'use_sim_time'}
    unknown = sorted(set(top) - known) + sorted(
        f'sim.{k}' for k in set(sim) - {f.name for f in dataclasses.fields(SimDriveSettings)}
    )
    if unknown:
        raise ValueError(f'unknown driver parameter(s): {", ".join(unknown)}')
    top.pop('use_sim_time', None)
    DriverParameters(**top, sim=SimDriveSettings(**sim))


def driver_arguments(params: dict[str, Any]) -> list[str]:
    """Return the parameters as command-line arguments of the installed executable."""
    args = ['--ros-args']
    for key, value in params.items():
        text = ('true' if value else 'false') if isinstance(value, bool) else str(value)
        args += ['-p', f'{key}:={text}']
    return args
