# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Which trajectories the controller takes, and why not: joint_trajectory_controller's rules.

ROS-free: ``TrajectoryRequest`` is a trajectory_msgs/JointTrajectory as plain data (the node
converts the message), and each rule returns '' or the one-line reason. The message checks
are JTC's (validate_trajectory_msg, in its order, with its error strings); this controller adds
what JTC leaves to the hardware: non-finite values, duplicate joint names, a negative first
time, and whether the joint can follow the planned x1d at all (``feasibility_refusal``:
position, velocity and the nominal current against the limits with the margins of
actuator_core.limits). A goal's own tolerances resolve as JTC's (0: the default, -1: none),
but an illegal one refuses the goal instead of falling back to the defaults silently.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from actuator_controller.trajectory import Segments, Waypoints
from actuator_controller.trajectory_settings import (
    GoalSettings,
    SegmentTolerances,
    StateTolerance,
)
from actuator_core import limits

#: JTC treats a last velocity within float32's epsilon as zero.
FLOAT32_EPSILON = float(np.finfo(np.float32).eps)
#: control_msgs/JointTolerance: -1 erases a default tolerance (JTC compares within float32's eps).
ERASE_TOLERANCE = -1.0
#: JTC's refusal of a goal while the controller is not active.
NOT_RUNNING = "Can't accept new action goals. Controller is not running."
JOINTS_MISMATCH = "Joints on incoming trajectory don't match the controller joints."
EMPTY_JOINT_NAMES = 'Empty joint names on incoming trajectory.'
EMPTY_TRAJECTORY = 'Empty trajectory received.'
EFFORT_REFUSED = (
    'Trajectories with effort fields are only supported for controllers using the '
    "'effort' command interface."
)


@dataclass(frozen=True)
class RequestPoint:
    """One trajectory_msgs/JointTrajectoryPoint: its fields as tuples (empty when absent)."""

    time_from_start_ns: int
    positions: tuple = ()
    velocities: tuple = ()
    accelerations: tuple = ()
    effort: tuple = ()


@dataclass(frozen=True)
class TrajectoryRequest:
    """One trajectory_msgs/JointTrajectory: header.stamp [ns] (0: start when taken) and points."""

    joint_names: tuple
    points: tuple  #: RequestPoint
    stamp_ns: int = 0


@dataclass(frozen=True)
class _Goal:
    """What the rules of trajectory_refusal look at: the request and the controller's side."""

    request: TrajectoryRequest
    joint_names: Sequence[str]
    allow_nonzero_end_velocity: bool
    now_ns: int


def _joint_count_refusal(goal: _Goal) -> str:
    """Refuse a trajectory naming more or fewer joints than the controller has."""
    return JOINTS_MISMATCH if len(goal.request.joint_names) != len(goal.joint_names) else ''


def _empty_names_refusal(goal: _Goal) -> str:
    """Refuse a trajectory without joint names."""
    return '' if goal.request.joint_names else EMPTY_JOINT_NAMES


def _empty_points_refusal(goal: _Goal) -> str:
    """Refuse a trajectory without points."""
    return '' if goal.request.points else EMPTY_TRAJECTORY


def _unknown_joint_refusal(goal: _Goal) -> str:
    """Refuse a trajectory naming a joint the controller does not have."""
    for name in goal.request.joint_names:
        if name not in goal.joint_names:
            return f"Incoming joint {name} doesn't match the controller's joints."
    return ''


def _duplicate_joint_refusal(goal: _Goal) -> str:
    """Refuse a trajectory naming a joint twice."""
    names = goal.request.joint_names
    for name in names:
        if names.count(name) > 1:
            return f'Joint {name} appears more than once on incoming trajectory.'
    return ''


def _end_velocity_refusal(goal: _Goal) -> str:
    """Refuse a last point that does not stop the joint, unless the controller allows it."""
    if goal.allow_nonzero_end_velocity:
        return ''
    for name, velocity in zip(goal.request.joint_names, goal.request.points[-1].velocities):
        if abs(velocity) > FLOAT32_EPSILON:
            return (
                f'Velocity of last trajectory point of joint {name} is not zero: {velocity:.15f}'
            )
    return ''


def _past_end_refusal(goal: _Goal) -> str:
    """Refuse a trajectory with a start time that ends before now."""
    request = goal.request
    if request.stamp_ns != 0:
        end_ns = request.stamp_ns + request.points[-1].time_from_start_ns
        if end_ns < goal.now_ns:
            return (
                f'Received trajectory with non-zero start time ({request.stamp_ns * 1e-9:f}) '
                f'that ends in the past ({end_ns * 1e-9:f})'
            )
    return ''


def _field_refusal(
    names: Sequence[str], i: int, field: str, values: tuple, allow_empty: bool
) -> str:
    """Refuse a field of point #i with a value per joint missing, or a non-finite value."""
    if not (allow_empty and not values) and len(values) != len(names):
        return (
            f'Mismatch between joint_names size ({len(names)}) and {field} '
            f'({len(values)}) at point #{i}.'
        )
    for name, value in zip(names, values):
        if not math.isfinite(value):
            return f'Non-finite {field} of joint {name} at point #{i}: {value}'
    return ''


def _point_refusal(names: Sequence[str], i: int, point: RequestPoint, previous_ns: int) -> str:
    """Refuse point #i: its time not after the previous one's, its fields, an effort field."""
    if i > 0 and point.time_from_start_ns <= previous_ns:
        return (
            f'Time between points {i - 1} and {i} is not strictly increasing, it is '
            f'{previous_ns * 1e-9:f} and {point.time_from_start_ns * 1e-9:f} respectively'
        )
    for field, values, allow_empty in (
        ('positions', point.positions, False),
        ('velocities', point.velocities, True),
        ('accelerations', point.accelerations, True),
    ):
        refusal = _field_refusal(names, i, field, values, allow_empty)
        if refusal:
            return refusal
    if point.effort:
        return EFFORT_REFUSED
    return ''


def _points_refusal(goal: _Goal) -> str:
    """Refuse the first point that fails a check of its own (points in order)."""
    previous_ns = 0
    for i, point in enumerate(goal.request.points):
        refusal = _point_refusal(goal.request.joint_names, i, point, previous_ns)
        if refusal:
            return refusal
        previous_ns = point.time_from_start_ns
    return ''


def _negative_start_refusal(goal: _Goal) -> str:
    """Refuse a first point before the trajectory's start."""
    first_ns = goal.request.points[0].time_from_start_ns
    return f'Time of point 0 is negative: {first_ns * 1e-9:f}' if first_ns < 0 else ''


def _mixed_fields_refusal(goal: _Goal) -> str:
    """Refuse points that carry different fields, or accelerations without velocities."""
    carried = {(bool(p.velocities), bool(p.accelerations)) for p in goal.request.points}
    if len(carried) > 1 or (False, True) in carried:
        return (
            'Points carry different fields (positions only, with velocities, or with velocities '
            'and accelerations: one kind for every point)'
        )
    return ''


#: The rules of trajectory_refusal, in the order they are checked (JTC's, then this controller's).
_TRAJECTORY_RULES: tuple[Callable[[_Goal], str], ...] = (
    _joint_count_refusal,
    _empty_names_refusal,
    _empty_points_refusal,
    _unknown_joint_refusal,
    _duplicate_joint_refusal,
    _end_velocity_refusal,
    _past_end_refusal,
    _points_refusal,
    _negative_start_refusal,
    _mixed_fields_refusal,
)


def trajectory_refusal(
    request: TrajectoryRequest,
    joint_names: Sequence[str],
    allow_nonzero_end_velocity: bool,
    now_ns: int,
) -> str:
    """'' when the trajectory may be taken, else why not (JTC's checks in JTC's order)."""
    goal = _Goal(request, joint_names, allow_nonzero_end_velocity, now_ns)
    for rule in _TRAJECTORY_RULES:
        refusal = rule(goal)
        if refusal:
            return refusal
    return ''


def waypoints(request: TrajectoryRequest, joint_names: Sequence[str]) -> Waypoints:
    """Return the request's points in the controller's joint order, times [s] from its start."""
    order = [request.joint_names.index(name) for name in joint_names]
    points = request.points

    def column(field: str):
        if not getattr(points[0], field):
            return None
        return np.array([getattr(p, field) for p in points], dtype=float)[:, order]

    return Waypoints(
        np.array([p.time_from_start_ns for p in points], dtype=float) * 1e-9,
        column('positions'),
        column('velocities'),
        column('accelerations'),
    )


def _resolve(default: float, requested: float) -> float:
    """JTC's resolve_tolerance_source: > 0 replaces, 0 keeps the default, -1 erases it."""
    if requested > 0.0:
        return requested
    if abs(requested - ERASE_TOLERANCE) < FLOAT32_EPSILON:
        return 0.0
    if requested < 0.0 or not math.isfinite(requested):
        raise ValueError(requested)
    return default


def resolve_tolerances(
    defaults: SegmentTolerances,
    joint_names: Sequence[str],
    path_tolerance: Sequence[tuple] = (),
    goal_tolerance: Sequence[tuple] = (),
    goal_time_tolerance_s: float = 0.0,
) -> tuple:
    """(tolerances, refusal): a goal's tolerances over the defaults, JTC's rules.

    ``path_tolerance``/``goal_tolerance``: (name, position, velocity, acceleration) per entry,
    as control_msgs/JointTolerance. An unknown joint or an illegal value refuses the goal
    (JTC falls back to the defaults with an error log).
    """
    try:
        goal_time_s = _resolve(defaults.goal_time_s, goal_time_tolerance_s)
    except ValueError:
        return defaults, f'Specified illegal goal_time_tolerance: {goal_time_tolerance_s:f}'
    resolved = {'path': list(defaults.path), 'goal': list(defaults.goal)}
    for which, entries in (('path', path_tolerance), ('goal', goal_tolerance)):
        for name, *values in entries:
            if name not in joint_names:
                return defaults, (
                    f"joint '{name}' specified in goal.{which}_tolerance does not exist"
                )
            i = list(joint_names).index(name)
            old = resolved[which][i]
            new = []
            for field, value, default in zip(StateTolerance._fields, values, old):
                try:
                    new.append(_resolve(default, value))
                except ValueError:
                    return defaults, (
                        f"joint '{name}' specified in goal.{which}_tolerance has an invalid "
                        f'{field} tolerance: {value:f} (0: the default, -1: none, else > 0)'
                    )
            resolved[which][i] = StateTolerance(*new)
    return SegmentTolerances(tuple(resolved['path']), tuple(resolved['goal']), goal_time_s), ''


def unchecked_note(tolerances: SegmentTolerances, joint_names: Sequence[str]) -> str:
    """'' or a warning: acceleration tolerances are not checked (the joint reports none)."""
    named = [
        name
        for name, path, goal in zip(joint_names, tolerances.path, tolerances.goal)
        if path.acceleration > 0.0 or goal.acceleration > 0.0
    ]
    if not named:
        return ''
    return (
        f'acceleration tolerances of {", ".join(named)} are not checked: the loop measures the '
        'angle and estimates the velocity, it has no acceleration to compare'
    )


def tolerance_violation(
    joint_names: Sequence[str], position_errors, velocity_errors, tolerances: Sequence
) -> str:
    """'' when every error is within its (non-zero) tolerance, else which one and by how much.

    ``velocity_errors`` None: no velocity to check (JTC: a state without velocities).
    """
    for i, (name, tolerance) in enumerate(zip(joint_names, tolerances)):
        error = position_errors[i]
        if tolerance.position > 0.0 and abs(error) > tolerance.position:
            return f'joint {name} position error {error:.6g} rad beyond {tolerance.position:g} rad'
        if velocity_errors is None:
            continue
        error = velocity_errors[i]
        if tolerance.velocity > 0.0 and abs(error) > tolerance.velocity:
            return (
                f'joint {name} velocity error {error:.6g} rad/s beyond '
                f'{tolerance.velocity:g} rad/s'
            )
    return ''


def feasibility_refusal(
    segments: Segments,
    joint_names: Sequence[str],
    settings: GoalSettings,
    theta1n: float,
    theta2n: float,
    current_limit_a: float,
) -> str:
    """'' when the joint can follow the planned x1d, else the first check it fails.

    On every segment's grid (``Segments.grid``): x1d within the soft position limits less
    GOAL_POSITION_MARGIN_RAD; |x1d'| within GOAL_VELOCITY_SHARE of the soft velocity limit;
    the nominal current (x1d'' - theta_2n x1d') / theta_1n of eq. (3) within GOAL_CURRENT_SHARE
    of the current limit (the rest for the disturbance and the feedback).
    """
    t, p, v, a = segments.grid()
    low = settings.position_min_rad + limits.GOAL_POSITION_MARGIN_RAD
    high = settings.position_max_rad - limits.GOAL_POSITION_MARGIN_RAD
    speed = limits.GOAL_VELOCITY_SHARE * settings.velocity_max_rad_s
    current = limits.GOAL_CURRENT_SHARE * current_limit_a
    nominal = (a - theta2n * v) / theta1n
    checks = (
        (
            (p < low) | (p > high),
            p,
            'rad',
            f'outside the soft position limits [{settings.position_min_rad:g}, '
            f'{settings.position_max_rad:g}] rad less a margin of '
            f'{limits.GOAL_POSITION_MARGIN_RAD:g} rad',
            'x1d',
        ),
        (
            np.abs(v) > speed,
            v,
            'rad/s',
            f'beyond {limits.GOAL_VELOCITY_SHARE:g} of the soft velocity limit '
            f'{settings.velocity_max_rad_s:g} rad/s',
            "x1d'",
        ),
        (
            np.abs(nominal) > current,
            nominal,
            'A',
            f'beyond {limits.GOAL_CURRENT_SHARE:g} of the current limit {current_limit_a:g} A '
            "(nominal current (x1d'' - theta2n x1d') / theta1n, eq. (3))",
            'nominal current',
        ),
    )
    for bad, values, unit, limit_text, what in checks:
        if np.any(bad):
            k, j = np.argwhere(bad)[0]
            return (
                f'Trajectory cannot be followed: joint {joint_names[j]} {what} '
                f'{values[k, j]:.4g} {unit} at {t[k] - t[0]:.3f} s is {limit_text}'
            )
    return ''
