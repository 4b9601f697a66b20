# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""ProcessMember: what ``runner.run_nodes`` asks of every node it runs (ROS-free).

One typed contract for every process of the project, whether it holds one node or a composed
loop: the managed nodes (joint, ESO, controller, driver), the recorder, the player, the live
view and the benchmark's floor nodes. ``run_nodes`` calls, in order:

  autostart  once every node of the process is built: bring the node up as its parameters say;
             False = refused (the node logged why), the process exits 2;
  (spin)     until a signal, or a node's ``finished`` (its run is over) or ``error`` (the reason
             it failed: exit 1);
  halt       stop acting now (a joint's gate to 0 A with the brake, the last safe-stop command);
  settled    the executor spins on until every node says it took what was delivered (the
             recorder: nothing new for a moment), at most ``SETTLE_LIMIT_S``;
  (acks)     RELIABLE subscribers acknowledge what was published;
  release    drop what was built and close what was opened; ``MemberError`` = it failed there
             (one line, exit 1: a bag that could not be closed).
"""

from __future__ import annotations

from typing import Optional

#: Longest spin after the halt for the nodes to settle [s].
SETTLE_LIMIT_S = 3.0


class MemberError(Exception):
    """A node failed while it was released: one line for the user, exit 1."""


class ProcessMember:
    """The run contract of a node in a process started by ``run_nodes``; defaults do nothing."""

    #: the node ended the run itself (a timed run over, a bag played through)
    finished: bool = False
    #: why the node failed, or None
    error: Optional[str] = None

    def autostart(self) -> bool:
        """Bring the node up as its parameters say; False when that was refused (logged)."""
        return True

    def halt(self) -> None:
        """Stop acting now; idempotent."""

    def settled(self) -> bool:
        """After the halt: whether the node has taken what was delivered to it."""
        return True

    def release(self) -> None:
        """Drop what was built, close what was opened; MemberError when that failed."""
