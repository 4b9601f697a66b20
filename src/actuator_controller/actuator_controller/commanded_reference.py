# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The reference of a commanded run (``reference: hold``): x1d from whatever program runs now.

A program is a ``trajectory.Hold`` or ``trajectory.Segments`` (a goal's plan, or a stop). The
assembly (actuator_core.assembly) samples it once per law sample on its own clock t and calls
``restart_from`` at the first sample and when a resync ends: the joint then holds the angle it
is at. ``TrajectoryExecution`` (goal_execution) switches programs between samples: a goal's
plan from the desired state the law just used, a stop from it (cancel) or from the joint's own
state (an aborted goal). A plan that ends moving is followed by its stop; one that ends at rest
by a hold of its last point.
"""

from __future__ import annotations

from typing import Sequence

from actuator_controller.reference_sample import ReferenceSample
from actuator_controller.trajectory import DesiredState, Hold, Segments, stop_segment


class CommandedReference:
    """x1d and its derivatives from the running program; holds until told otherwise."""

    name = 'hold'

    def __init__(self, max_deceleration: Sequence[float], joint: int = 0) -> None:
        """``max_deceleration``: each joint's bound on |x1d''| of a stop [rad/s^2].

        ``joint``: which joint's x1d ``sample`` gives the assembly (the loop has one today).
        """
        self.max_deceleration = tuple(max_deceleration)
        self.joint = joint
        self.program: Hold | Segments = Hold((0.0,) * len(self.max_deceleration))
        self.restarts = 0

    # --- the assembly's side ---------------------------------------------------------------------
    def restart_from(self, positions) -> None:
        """Hold the joint's angle(s) (the assembly: first sample, end of a resync)."""
        self.program = Hold(positions)
        self.restarts += 1

    def state(self, t: float) -> DesiredState:
        """Every joint's desired state at t; a plan past its end gives way to its stop or hold."""
        program = self.program
        if t >= program.end_s and isinstance(program, Segments):
            end = program.sample(program.end_s)
            self.program = (
                Hold(end.positions) if program.is_stop else self._rest_after(program.end_s, end)
            )
            program = self.program
        return program.sample(t)

    def sample(self, t) -> ReferenceSample:
        """x1d, x1d', x1d'' of the loop's joint at t [s] (the Reference protocol)."""
        state = self.state(t)
        j = self.joint
        return ReferenceSample(state.positions[j], state.velocities[j], state.accelerations[j])

    # --- the execution's side --------------------------------------------------------------------
    def follow(self, segments: Segments) -> None:
        """Run a goal's plan (it starts from the desired state at its first segment's start)."""
        self.program = segments

    def stop(self, t: float, start: DesiredState) -> None:
        """Bring ``start`` (the desired or the joint's own state at t) to rest, then hold."""
        self.program = self._rest_after(t, start)

    @property
    def moving(self) -> bool:
        """Whether a plan or a stop runs (not a hold)."""
        return isinstance(self.program, Segments)

    def _rest_after(self, t: float, start: DesiredState):
        """Return a stop from ``start`` at t within the deceleration bounds, or a hold at rest."""
        segments = stop_segment(t, start, self.max_deceleration)
        return Hold(start.positions) if segments is None else segments
