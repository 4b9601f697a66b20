# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Subscriptions and publications of the loop's hot path through the wire codec (wire.py).

A subscription here takes the serialized bytes (rclpy ``raw=True``) and hands its callback a view
of the message; a publisher is given ``Codec.encode``'s bytes. The messages on the wire are the
same: any ROS 2 tool reads and writes them as usual.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Callable

from rclpy.node import Node
from rclpy.serialization import deserialize_message

from actuator_ros.wire import Codec

#: Shortest interval between two log lines about refused bytes on one topic [s].
MALFORMED_LOG_INTERVAL_S = 1.0


@lru_cache(maxsize=None)
def codec(cls) -> Codec:
    """Return the codec of a message class; what it does not read goes to rclpy's own."""
    return Codec(cls, fallback=lambda data: deserialize_message(bytes(data), cls))


def subscribe_views(node: Node, cls, topic: str, callback: Callable, qos, **kwargs):
    """``node.create_subscription`` whose ``callback`` gets a view of each message.

    Bytes that are no ``cls`` are refused with an error line (one a second at most).
    """
    read = codec(cls).decode
    logger = node.get_logger()

    def take(data: bytes) -> None:
        try:
            msg = read(data)
        except Exception as exc:  # WireError, or rclpy's deserialisation error in the fallback
            logger.error(
                f'{topic}: message refused, not a {cls.__name__}: {exc}',
                throttle_duration_sec=MALFORMED_LOG_INTERVAL_S,
            )
            return
        callback(msg)

    return node.create_subscription(cls, topic, take, qos, raw=True, **kwargs)
