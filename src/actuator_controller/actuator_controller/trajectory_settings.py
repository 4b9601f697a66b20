# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What a commanded trajectory is judged by: joint_trajectory_controller's parameters, as specs.

Names as JTC's (``constraints.goal_time``, ``constraints.<joint>.trajectory``, ...), so a JTC
configuration carries over; the soft limits share the joint node's names (``position_min_rad``
...), so one ``/**`` section sets both nodes. docs/reference/parameters.md lists them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from actuator_core import limits
from actuator_core.params import require_below, spec, validate


class StateTolerance(NamedTuple):
    """|error| bounds of one joint [rad, rad/s, rad/s^2]; 0 leaves that one unchecked (JTC)."""

    position: float = 0.0
    velocity: float = 0.0
    acceleration: float = 0.0


class SegmentTolerances(NamedTuple):
    """A goal's tolerances: per joint along the path and at the end, and the end's time slack."""

    path: tuple  #: StateTolerance per joint, checked until the last point's time
    goal: tuple  #: StateTolerance per joint, to be met after it
    goal_time_s: float  #: how long after the last point's time; 0 waits for ever


@dataclass(frozen=True)
class TrajectoryConstraints:
    """``constraints.*``: the defaults of every goal's end (JTC's names and defaults)."""

    stopped_velocity_tolerance: float = spec(
        0.01,
        "goal tolerance on |x2_hat - x1d'| at a goal's end (the joint has stopped)",
        'rad/s',
        0.0,
        100.0,
    )
    goal_time: float = spec(
        0.0,
        "time after a goal's last point within which the joint must be within its goal "
        'tolerances, else the goal aborts with GOAL_TOLERANCE_VIOLATED; 0 waits for ever',
        's',
        0.0,
        1.0e6,
    )

    def __post_init__(self) -> None:
        """Refuse out-of-range values."""
        validate(self)


@dataclass(frozen=True)
class JointConstraints:
    """``constraints.<joint>.*``: one joint's tolerances and stop (JTC's names)."""

    trajectory: float = spec(
        0.0,
        'path tolerance: |e| beyond it before the last point aborts the goal with '
        'PATH_TOLERANCE_VIOLATED; 0 unchecked',
        'rad',
        0.0,
        100.0,
    )
    goal: float = spec(
        0.0, "goal tolerance on |e| at the goal's end; 0 unchecked", 'rad', 0.0, 100.0
    )
    max_deceleration_on_cancel: float = spec(
        limits.STOP_DECELERATION_RAD_S2,
        "bound on |x1d''| while a cancel or an aborted goal brings the desired motion to rest "
        '(half of what the current limit commands at the nominal model)',
        'rad/s^2',
        0.0,
        1.0e5,
        low_open=True,
    )

    def __post_init__(self) -> None:
        """Refuse out-of-range values."""
        validate(self)


@dataclass(frozen=True)
class GoalSettings:
    """How goals are taken: the end-velocity rule, the feedback rate and the soft limits."""

    allow_nonzero_velocity_at_trajectory_end: bool = spec(
        False,
        "accept goals whose last point's velocity is not zero (the desired motion then comes to "
        'rest within max_deceleration_on_cancel after it)',
    )
    action_monitor_rate: float = spec(
        20.0,
        'rate of goal feedback and of results (the goals thread, off the control path)',
        'Hz',
        0.1,
        1000.0,
    )
    position_min_rad: float = spec(
        -limits.POSITION_LIMIT_RAD,
        "the joint's soft limit (set it with the joint node's, e.g. in a /** section): goals "
        f'whose x1d comes within {limits.GOAL_POSITION_MARGIN_RAD:g} rad of it are refused',
        'rad',
        -limits.POSITION_LIMIT_RAD,
        limits.POSITION_LIMIT_RAD,
    )
    position_max_rad: float = spec(
        limits.POSITION_LIMIT_RAD,
        "the joint's soft limit (set it with the joint node's): goals whose x1d comes within "
        f'{limits.GOAL_POSITION_MARGIN_RAD:g} rad of it are refused',
        'rad',
        -limits.POSITION_LIMIT_RAD,
        limits.POSITION_LIMIT_RAD,
    )
    velocity_max_rad_s: float = spec(
        limits.VELOCITY_LIMIT_RAD_S,
        "the joint's soft speed limit (set it with the joint node's): goals whose |x1d'| "
        f'exceeds {limits.GOAL_VELOCITY_SHARE:g} of it are refused',
        'rad/s',
        0.0,
        limits.VELOCITY_LIMIT_RAD_S,
        low_open=True,
    )

    def __post_init__(self) -> None:
        """Refuse out-of-range values and an empty position window."""
        validate(self)
        require_below(self, 'position_min_rad', 'position_max_rad')


@dataclass(frozen=True)
class TrajectorySettings:
    """Everything goals are judged by, for the loop's joints in their order."""

    joint_names: tuple
    goal: GoalSettings = GoalSettings()
    constraints: TrajectoryConstraints = TrajectoryConstraints()
    joints: tuple = ()  #: JointConstraints per joint (default: JTC's for each)

    def __post_init__(self) -> None:
        """One JointConstraints per joint."""
        if not self.joints:
            object.__setattr__(self, 'joints', tuple(JointConstraints() for _ in self.joint_names))
        if len(self.joints) != len(self.joint_names):
            raise ValueError(
                f'{len(self.joints)} joint constraints for {len(self.joint_names)} joints'
            )

    def default_tolerances(self) -> SegmentTolerances:
        """Return the tolerances of a goal that names none (JTC's get_segment_tolerances)."""
        return SegmentTolerances(
            path=tuple(StateTolerance(position=j.trajectory) for j in self.joints),
            goal=tuple(
                StateTolerance(
                    position=j.goal, velocity=self.constraints.stopped_velocity_tolerance
                )
                for j in self.joints
            ),
            goal_time_s=self.constraints.goal_time,
        )

    @property
    def max_deceleration(self) -> tuple:
        """Each joint's bound on |x1d''| while stopping [rad/s^2]."""
        return tuple(j.max_deceleration_on_cancel for j in self.joints)
