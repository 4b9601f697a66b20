# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Process-wide hooks on the publishers a managed node creates (ROS-free).

A process that records its own publications (actuator_bag.tap, in a loop container) installs a
hook before it builds its nodes; each publisher a ``ManagedNode`` creates passes through it and
may come back wrapped. A wrapper keeps the publisher it wraps as ``inner``, so destroying the
wrapper destroys that. No hook installed: a node gets rclpy's publisher itself.
"""

from __future__ import annotations

from typing import Any, Callable

#: hook(node, publisher, msg_type) -> the publisher, or a wrapper whose ``inner`` it is.
Hook = Callable[[Any, Any, type], Any]
_HOOKS: list[Hook] = []


def install(hook: Hook) -> None:
    """Pass every publisher a managed node creates from now on through ``hook``."""
    _HOOKS.append(hook)


def uninstall(hook: Hook) -> None:
    """Stop passing publishers through ``hook`` (ones already wrapped stay wrapped)."""
    if hook in _HOOKS:
        _HOOKS.remove(hook)


def hooked(node: Any, publisher: Any, msg_type: type) -> Any:
    """Return ``publisher`` passed through every installed hook."""
    for hook in _HOOKS:
        publisher = hook(node, publisher, msg_type)
    return publisher


def inner(publisher: Any) -> Any:
    """Return rclpy's publisher under any wrappers (what destroy_publisher needs)."""
    while hasattr(publisher, 'inner'):
        publisher = publisher.inner
    return publisher
