# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""rclpy helpers shared by the recorder and the player.

Message classes, QoS conversion, and their main().
"""

from __future__ import annotations

import argparse
import importlib
import sys
from typing import Any, Callable, Optional, Sequence

from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.utilities import remove_ros_args

from actuator_ros.process_member import MemberError, ProcessMember
from actuator_ros.realtime import RealtimeSettings
from actuator_ros.runner import run_nodes

from .bag_format import QosProfile
from .errors import BagError
from .msgdefs import normalize_msgtype


def run_bag_node(
    prog: str,
    description: str,
    add_arguments: Callable[[argparse.ArgumentParser], None],
    node_class: Callable[[argparse.Namespace, RealtimeSettings], ProcessMember],
    argv: Optional[Sequence[str]] = None,
) -> int:
    """Run the recorder's or the player's node in a process started by ``run_nodes``.

    Its options (the defaults of its parameters) come from the command line; a BagError while
    it is built (an output that exists, no bag) is one line ``prog: error: ...``, exit 1.
    """
    args = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(prog=prog, description=description)
    add_arguments(parser)
    try:
        options = parser.parse_args(remove_ros_args([prog, *args])[1:])
    except Exception:  # noqa: BLE001 - run_nodes reports bad ROS arguments in one line
        options = parser.parse_args([])

    def build(settings: RealtimeSettings) -> ProcessMember:
        try:
            return node_class(options, settings)
        except BagError as err:
            raise MemberError(str(err)) from None

    return run_nodes(prog, description, [build], prog, args, add_arguments)


def message_class(msgtype: str) -> Any:
    """Return the Python class of a ROS message type ``pkg/msg/Type``.

    BagError when it is not installed.
    """
    pkg, _, name = normalize_msgtype(msgtype).split('/')
    try:
        module = importlib.import_module(f'{pkg}.msg')
        return getattr(module, name)
    except (ImportError, AttributeError):
        raise BagError(
            f'message type {pkg}/msg/{name} is not installed (cannot import {pkg}.msg.{name})'
        ) from None


def _pair(duration: Duration) -> tuple[int, int]:
    """Convert a Duration to (sec, nsec)."""
    ns = int(duration.nanoseconds)
    return (ns // 1_000_000_000, ns % 1_000_000_000)


def to_bag_qos(qos: QoSProfile) -> QosProfile:
    """Convert an rclpy QoS profile to the bag's offered-QoS record."""
    return QosProfile(
        history=HistoryPolicy(qos.history).name.lower(),
        depth=int(qos.depth),
        reliability=ReliabilityPolicy(qos.reliability).name.lower(),
        durability=DurabilityPolicy(qos.durability).name.lower(),
        deadline=_pair(qos.deadline),
        lifespan=_pair(qos.lifespan),
        liveliness=LivelinessPolicy(qos.liveliness).name.lower(),
        liveliness_lease_duration=_pair(qos.liveliness_lease_duration),
        avoid_ros_namespace_conventions=bool(qos.avoid_ros_namespace_conventions),
    )


def make_qos(reliability: str, depth: int) -> QoSProfile:
    """KEEP_LAST(depth), VOLATILE profile with the given reliability.

    ``reliability`` is 'reliable' or 'best_effort'.
    """
    policies = {
        'reliable': ReliabilityPolicy.RELIABLE,
        'best_effort': ReliabilityPolicy.BEST_EFFORT,
    }
    if reliability not in policies:
        raise BagError(f'reliability must be reliable or best_effort, not {reliability!r}')
    if depth < 1:
        raise BagError(f'queue depth must be >= 1, not {depth}')
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=policies[reliability],
        durability=DurabilityPolicy.VOLATILE,
    )
