# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""One publisher per control input, seen when a publisher matches, not by polling.

``GraphGuard`` gives each control subscription ``SubscriptionEventCallbacks(matched=...)``
(rclpy 7.1): the middleware calls it when a publisher is connected or disconnected, in
discovery, before that publisher's first message is delivered (measured with
``actuator_bench.guard_probe``). On every change it counts the matched publishers of each
watched topic and, when one has more than one, tells the node at once (``on_change``) with the
publishers' node names and GIDs from the graph, so the log says who joined. A topic the node
does not subscribe (the controller's own output) is counted by ``poll``.

Per-message identity: rclpy 7.1.6's message info carries timestamps and the publication
sequence number, not the publisher's GID, under either executor, so a node cannot tell which
publisher one message came from; binding to the one peer is therefore done on the graph: the
node acts on an input only while exactly one publisher is matched on it
(docs/safety.md#one-publisher-per-input).
"""

from __future__ import annotations

from typing import Callable

from rclpy.event_handler import SubscriptionEventCallbacks


class GraphGuard:
    """Counts matched publishers per watched topic; reports every change of the conflict."""

    def __init__(self, node, on_change: Callable[[str], None]):
        """``on_change(conflict)``: '' when every topic has one publisher at most, else who."""
        self.node = node
        self.on_change = on_change
        self.counts: dict[str, int] = {}
        self.conflict = ''
        self.changes = 0

    def callbacks(self, topic: str) -> SubscriptionEventCallbacks:
        """Event callbacks for the subscription of ``topic`` (pass as ``event_callbacks``)."""
        self.counts.setdefault(topic, 0)
        return SubscriptionEventCallbacks(matched=lambda info: self.matched(topic, info))

    def matched(self, topic: str, info) -> None:
        """Take a matched event of ``topic``: ``info.current_count`` publishers now."""
        self.set_count(topic, int(info.current_count))

    def poll(self, topics) -> None:
        """Count the publishers of topics this node does not subscribe (graph query)."""
        for topic in topics:
            self.set_count(topic, self.node.count_publishers(topic))

    def set_count(self, topic: str, count: int) -> None:
        """Record ``count`` publishers on ``topic``; report a change of the conflict."""
        self.counts[topic] = count
        conflict = ', '.join(
            f'{n} publishers on {t} ({self.who(t)})'
            for t, n in sorted(self.counts.items())
            if n > 1
        )
        if conflict != self.conflict:
            self.conflict = conflict
            self.changes += 1
            self.on_change(conflict)

    def who(self, topic: str) -> str:
        """Name the publishers of ``topic`` by node and GID, as the graph knows them."""
        try:
            infos = self.node.get_publishers_info_by_topic(self.resolve(topic))
        except Exception as exc:  # the graph query failing must not end the guard
            return f'publishers unknown: {exc}'
        return '; '.join(
            f'{i.node_namespace.rstrip("/")}/{i.node_name} gid '
            + ''.join(f'{b:02x}' for b in i.endpoint_gid[:16])
            for i in infos
        )

    def resolve(self, topic: str) -> str:
        """Return the fully qualified name of a relative topic."""
        return self.node.resolve_topic_name(topic)
