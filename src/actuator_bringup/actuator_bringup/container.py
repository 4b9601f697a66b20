# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

r"""The loop's nodes composed in one process on one executor, as ROS 2 components are.

    ros2 run actuator_bringup loop_container --nodes plant controller eso --ros-args \\
        --params-file case2_pp_nftsmc_eso.yaml -p actuator_plant:mode:=sim ...

Each node stays the node it is when run alone (its name, parameters, lifecycle, checks and
guards); only the process is shared. Messages between nodes of one process stay in one DDS
participant, so Fast DDS hands them over without the network path (measured:
docs/performance.md#current-figures). Parameters go to one node by the ``node:name:=value`` form of
``--ros-args -p``, or by the node's section of a parameter file; the process's real-time
settings (``thread_priority`` ...) are those of the first node named.

``--record BAG``: the container records what its nodes publish itself (actuator_bag.tap: a
writer process gets the bytes over a pipe; no DDS subscriber, no recorder process), for a
lockstep in sim time (composition.compose says why not in real time).
"""

from __future__ import annotations

import argparse
import sys
from typing import Callable, Sequence

#: Node kinds the container can hold: key -> (module, class, node name).
KINDS = {
    'plant': ('actuator_plant.plant_node', 'PlantNode', 'actuator_plant'),
    'driver': ('actuator_cia402.driver_node', 'Cia402DriverNode', 'actuator_cia402_driver'),
    'eso': ('actuator_eso.eso_node', 'EsoNode', 'actuator_eso'),
    'controller': ('actuator_controller.controller_node', 'ControllerNode', 'actuator_controller'),
}


def node_names(keys: Sequence[str]) -> list[str]:
    """Node names of the container's members, in order."""
    return [KINDS[k][2] for k in keys]


def _factory(key: str) -> Callable:
    """Return the class of node kind ``key`` (imported on demand: rclpy is slow to import)."""
    import importlib

    module, cls, _ = KINDS[key]
    return getattr(importlib.import_module(module), cls)


def _arguments(parser: argparse.ArgumentParser) -> None:
    """Add the container's own option to ``parser``."""
    parser.add_argument(
        '--nodes',
        nargs='+',
        choices=sorted(KINDS),
        default=['plant', 'controller', 'eso'],
        help='the nodes to run in this process, built in this order (default: plant controller '
        'eso; composition.COMPOSABLE says why)',
    )
    parser.add_argument(
        '--record',
        metavar='BAG',
        default='',
        help='record what these nodes publish into the bag folder BAG (which must not exist), '
        'in-process (actuator_bag.tap); sim time only',
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the named nodes in this process until a signal or the run's end."""
    import rclpy.utilities

    from actuator_ros.runner import run_nodes

    args = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(prog='loop_container', description=__doc__.splitlines()[0])
    _arguments(parser)
    try:
        own = parser.parse_args(rclpy.utilities.remove_ros_args(args))
        keys, bag = own.nodes, own.record
    except Exception:  # noqa: BLE001 - run_nodes reports bad ROS arguments in one line
        keys, bag = ['plant'], ''
    if len(set(keys)) != len(keys):
        print(f'loop_container: each node once, got {" ".join(keys)}', file=sys.stderr)
        return 2
    recording = _start_recording(bag) if bag else None
    if recording is False:
        return 2
    try:
        code = run_nodes(
            'loop_container',
            __doc__.splitlines()[0],
            [_factory(k) for k in keys],
            node_names(keys)[0],
            args,
            own_arguments=_arguments,
        )
    finally:
        recorded = recording is None or recording.close()
    return code or (0 if recorded else 1)


def _start_recording(bag: str):
    """Start the in-process recording into ``bag`` and hook it in; False (one line) if refused."""
    from pathlib import Path

    from actuator_bag.tap import InProcessRecording
    from actuator_ros import publisher_hooks

    if Path(bag).exists():
        print(f'loop_container: {bag} exists already, not overwriting', file=sys.stderr)
        return False
    recording = InProcessRecording(Path(bag))
    publisher_hooks.install(recording.hook)
    return recording


if __name__ == '__main__':
    raise SystemExit(main())
