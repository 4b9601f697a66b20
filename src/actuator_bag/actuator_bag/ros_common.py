# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""rclpy helpers shared by the recorder and the player.

Message classes, QoS conversion, signals, executors.
"""

from __future__ import annotations

import importlib
import signal
from types import FrameType
from typing import Any, Optional

from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from .bag_format import QosProfile
from .errors import BagError
from .msgdefs import normalize_msgtype

#: Executors a node can be run with.
EXECUTORS = ('events', 'single_threaded')  # actuator_ros.runner.make_executor's names


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


class StopFlag:
    """Turns SIGINT and SIGTERM into a flag that a spin loop checks.

    For rclpy.init with signal handling off.
    """

    def __init__(self) -> None:
        """Not installed yet; call install()."""
        self.requested = False
        self.signum: Optional[int] = None

    def install(self) -> None:
        """Handle SIGINT and SIGTERM from now on."""
        signal.signal(signal.SIGINT, self._handle)
        signal.signal(signal.SIGTERM, self._handle)

    def _handle(self, signum: int, frame: Optional[FrameType]) -> None:
        """Record the request; the spin loop ends at its next check."""
        self.requested = True
        self.signum = signum
