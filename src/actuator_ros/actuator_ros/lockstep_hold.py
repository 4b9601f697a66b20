# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A sim lockstep's output held until every reader of the next node has matched.

RELIABLE keeps nothing for a reader that has not matched, and a lockstep answers each sample
once: a message sent before the reader that waits for it matched is lost, and the loop waits for
good ("sim: no command for sample 0"). Counting one reader is not enough: the recorder (started
first) or the live view can be the one that matched, while the controller's or the joint's reader
has not yet. So an output is held until its publisher has ``subscribers`` readers (the run
description counts them), then sent in order; from then on it is published as it comes (a reader
that leaves later, a recorder at its end, must not stop the loop).
"""

from __future__ import annotations

import threading
from typing import Any, Protocol


class _Publisher(Protocol):
    def publish(self, msg: Any) -> None: ...

    def get_subscription_count(self) -> int: ...


class LockstepHold:
    """Hold ``publish`` until ``publisher`` has ``subscribers`` readers once; 0: never hold."""

    def __init__(self, publisher: _Publisher, subscribers: int) -> None:
        """Hold the messages of ``publisher`` until it has had ``subscribers`` readers."""
        self.publisher = publisher
        self.subscribers = subscribers
        self.released = subscribers <= 0
        self.unsent: list = []
        self._lock = threading.Lock()

    def publish(self, msg: Any) -> None:
        """Publish ``msg``, or hold it (after what is held) until the readers are there."""
        if self.released:
            self.publisher.publish(msg)
            return
        with self._lock:
            self.unsent.append(msg)
            self._release_if_matched(self.publisher.get_subscription_count())

    def on_matched(self, _info: Any = None) -> None:
        """Take a matched event of the publisher: count its readers again.

        The publisher's own count, not the event's: an in-process recording counts as one reader
        that no event reports (actuator_bag.tap).
        """
        with self._lock:
            self._release_if_matched(self.publisher.get_subscription_count())

    def _release_if_matched(self, readers: int) -> None:
        if self.released or readers < self.subscribers:
            return
        held, self.unsent = self.unsent, []
        for msg in held:
            self.publisher.publish(msg)
        self.released = True


def create_held_publisher(
    node: Any, msg_type: Any, topic: str, qos: Any, subscribers: int
) -> tuple[Any, LockstepHold]:
    """Return a lifecycle publisher of ``node`` and its hold (``subscribers`` 0: none).

    The node publishes through the hold; the publisher's matched events reach it.
    """
    from rclpy.event_handler import PublisherEventCallbacks

    holder: list[LockstepHold] = []
    publisher = node.create_lifecycle_publisher(
        msg_type,
        topic,
        qos,
        event_callbacks=PublisherEventCallbacks(matched=lambda info: holder[0].on_matched(info)),
    )
    holder.append(LockstepHold(publisher, subscribers))
    return publisher, holder[0]
