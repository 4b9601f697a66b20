# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Which trajectories the controller takes (actuator_controller.goal_rules), message by message.

The refusal strings are joint_trajectory_controller's (validate_trajectory_msg) where it has
one; the rest are this controller's own.
"""

import math

import numpy as np
import pytest

from actuator_controller.goal_rules import (
    EFFORT_REFUSED,
    EMPTY_TRAJECTORY,
    JOINTS_MISMATCH,
    RequestPoint,
    TrajectoryRequest,
    feasibility_refusal,
    resolve_tolerances,
    tolerance_violation,
    trajectory_refusal,
    unchecked_note,
    waypoints,
)
from actuator_controller.trajectory import DesiredState, Waypoints, plan
from actuator_controller.trajectory_settings import (
    GoalSettings,
    JointConstraints,
    SegmentTolerances,
    StateTolerance,
    TrajectoryConstraints,
    TrajectorySettings,
)
from actuator_core import limits

JOINTS = ('joint',)
S = 1_000_000_000


def _request(*points, names=JOINTS, stamp_ns=0):
    return TrajectoryRequest(tuple(names), tuple(points), stamp_ns)


def _point(t_s, positions=(0.5,), velocities=(), accelerations=(), effort=()):
    return RequestPoint(int(t_s * S), positions, velocities, accelerations, effort)


def _refusal(request, allow_nonzero=False, now_ns=5 * S, joints=JOINTS):
    return trajectory_refusal(request, joints, allow_nonzero, now_ns)


def test_a_well_formed_trajectory_is_taken():
    assert _refusal(_request(_point(0.5), _point(1.0, (0.2,)))) == ''
    assert _refusal(_request(_point(1.0, (0.2,), (0.0,), (0.0,)))) == ''


@pytest.mark.parametrize(
    'request_, expected',
    [
        (_request(_point(1.0), names=()), JOINTS_MISMATCH),
        (_request(_point(1.0, (0.1, 0.2)), names=('joint', 'other')), JOINTS_MISMATCH),
        (_request(), EMPTY_TRAJECTORY),
        (
            _request(_point(1.0), names=('elbow',)),
            "Incoming joint elbow doesn't match the controller's joints.",
        ),
        (
            _request(_point(1.0, (0.5,), (0.25,))),
            'Velocity of last trajectory point of joint joint is not zero: 0.250000000000000',
        ),
        (
            _request(_point(1.0), stamp_ns=2 * S),
            'Received trajectory with non-zero start time (2.000000) that ends in the past '
            '(3.000000)',
        ),
        (
            _request(_point(1.0), _point(1.0)),
            'Time between points 0 and 1 is not strictly increasing, it is 1.000000 and 1.000000 '
            'respectively',
        ),
        (
            _request(_point(1.0), _point(0.5)),
            'Time between points 0 and 1 is not strictly increasing, it is 1.000000 and 0.500000 '
            'respectively',
        ),
        (
            _request(_point(1.0, ())),
            'Mismatch between joint_names size (1) and positions (0) at point #0.',
        ),
        (
            _request(_point(0.5), _point(1.0, (0.1,), (0.0, 0.0))),
            'Mismatch between joint_names size (1) and velocities (2) at point #1.',
        ),
        (
            _request(_point(1.0, (0.1,), (0.0,), (1.0, 2.0))),
            'Mismatch between joint_names size (1) and accelerations (2) at point #0.',
        ),
        (_request(_point(1.0, effort=(1.0,))), EFFORT_REFUSED),
    ],
)
def test_jtc_refusals_with_jtc_strings(request_, expected):
    assert _refusal(request_) == expected


def test_joint_names_the_same_length_but_repeated_are_refused():
    request = _request(_point(1.0, (0.1, 0.2)), names=('a', 'a'))
    assert _refusal(request, joints=('a', 'b')) == (
        'Joint a appears more than once on incoming trajectory.'
    )


def test_a_nonzero_last_velocity_is_taken_when_allowed_and_float32_eps_counts_as_zero():
    moving = _request(_point(1.0, (0.5,), (0.25,)))
    assert _refusal(moving, allow_nonzero=True) == ''
    assert _refusal(_request(_point(1.0, (0.5,), (1e-8,)))) == ''


def test_a_start_in_the_past_is_taken_while_the_trajectory_still_ends_ahead():
    assert _refusal(_request(_point(1.0), stamp_ns=4_500_000_000), now_ns=5 * S) == ''


@pytest.mark.parametrize(
    'point, expected',
    [
        (_point(1.0, (math.nan,)), 'Non-finite positions of joint joint at point #0: nan'),
        (
            _point(1.0, (0.1,), (math.inf,)),
            'Non-finite velocities of joint joint at point #0: inf',
        ),
        (_point(-0.5), 'Time of point 0 is negative: -0.500000'),
    ],
)
def test_this_controllers_own_refusals(point, expected):
    assert _refusal(_request(point), allow_nonzero=True) == expected


def test_points_must_all_carry_the_same_fields():
    mixed = _request(_point(0.5, (0.1,), (0.2,)), _point(1.0, (0.2,)))
    no_velocity = _request(_point(1.0, (0.2,), (), (0.0,)))
    expected = (
        'Points carry different fields (positions only, with velocities, or with velocities '
        'and accelerations: one kind for every point)'
    )
    assert _refusal(mixed) == expected
    assert _refusal(no_velocity) == expected


def test_waypoints_are_reordered_to_the_controllers_joints_in_seconds():
    request = _request(
        _point(0.25, (1.0, 2.0), (0.1, 0.2)),
        _point(0.5, (3.0, 4.0), (0.0, 0.0)),
        names=('b', 'a'),
    )
    wp = waypoints(request, ('a', 'b'))
    np.testing.assert_array_equal(wp.times_s, [0.25, 0.5])
    np.testing.assert_array_equal(wp.positions, [[2.0, 1.0], [4.0, 3.0]])
    np.testing.assert_array_equal(wp.velocities, [[0.2, 0.1], [0.0, 0.0]])
    assert wp.accelerations is None


DEFAULTS = TrajectorySettings(
    ('a', 'b'),
    constraints=TrajectoryConstraints(stopped_velocity_tolerance=0.02, goal_time=0.5),
    joints=(JointConstraints(trajectory=0.1, goal=0.05), JointConstraints()),
).default_tolerances()


def test_default_tolerances_are_jtcs():
    assert DEFAULTS == SegmentTolerances(
        path=(StateTolerance(0.1), StateTolerance(0.0)),
        goal=(StateTolerance(0.05, 0.02), StateTolerance(0.0, 0.02)),
        goal_time_s=0.5,
    )


def test_goal_tolerances_zero_keeps_the_default_minus_one_erases_positive_replaces():
    tolerances, refusal = resolve_tolerances(
        DEFAULTS,
        ('a', 'b'),
        path_tolerance=[('a', -1.0, 0.3, 0.0), ('b', 0.2, 0.0, 0.0)],
        goal_tolerance=[('b', 0.0, -1.0, 0.0)],
        goal_time_tolerance_s=2.0,
    )
    assert refusal == ''
    assert tolerances.path == (StateTolerance(0.0, 0.3, 0.0), StateTolerance(0.2, 0.0, 0.0))
    assert tolerances.goal == (StateTolerance(0.05, 0.02), StateTolerance(0.0, 0.0))
    assert tolerances.goal_time_s == 2.0
    unchanged, refusal = resolve_tolerances(DEFAULTS, ('a', 'b'))
    assert (unchanged, refusal) == (DEFAULTS, '')


@pytest.mark.parametrize(
    'kwargs, expected',
    [
        (
            {'path_tolerance': [('c', 0.1, 0.0, 0.0)]},
            "joint 'c' specified in goal.path_tolerance does not exist",
        ),
        (
            {'goal_tolerance': [('a', 0.0, -0.5, 0.0)]},
            "joint 'a' specified in goal.goal_tolerance has an invalid velocity tolerance: "
            '-0.500000 (0: the default, -1: none, else > 0)',
        ),
        ({'goal_time_tolerance_s': -3.0}, 'Specified illegal goal_time_tolerance: -3.000000'),
    ],
)
def test_illegal_tolerances_refuse_the_goal(kwargs, expected):
    tolerances, refusal = resolve_tolerances(DEFAULTS, ('a', 'b'), **kwargs)
    assert refusal == expected
    assert tolerances == DEFAULTS


def test_acceleration_tolerances_are_accepted_but_said_to_be_unchecked():
    tolerances, _ = resolve_tolerances(DEFAULTS, ('a', 'b'), goal_tolerance=[('b', 0, 0, 0.4)])
    assert unchecked_note(tolerances, ('a', 'b')) == (
        'acceleration tolerances of b are not checked: the loop measures the angle and '
        'estimates the velocity, it has no acceleration to compare'
    )
    assert unchecked_note(DEFAULTS, ('a', 'b')) == ''


def test_tolerance_violation_names_the_joint_the_quantity_and_the_amounts():
    tolerances = (StateTolerance(0.1, 0.5), StateTolerance(0.0, 0.2))
    assert tolerance_violation(('a', 'b'), [0.05, 3.0], [0.4, 0.1], tolerances) == ''
    assert tolerance_violation(('a', 'b'), [-0.15, 0.0], [0.0, 0.0], tolerances) == (
        'joint a position error -0.15 rad beyond 0.1 rad'
    )
    assert tolerance_violation(('a', 'b'), [0.0, 0.0], [0.0, -0.3], tolerances) == (
        'joint b velocity error -0.3 rad/s beyond 0.2 rad/s'
    )
    assert tolerance_violation(('a', 'b'), [0.0, 0.0], None, tolerances) == ''


REST = DesiredState((0.0,), (0.0,), (0.0,))
T1N, T2N, LIMIT = limits.THETA1N, limits.THETA2N, limits.CURRENT_LIMIT_A


def _feasibility(points, positions, settings=GoalSettings()):
    wp = Waypoints(np.asarray(points, dtype=float), np.asarray(positions, dtype=float)[:, None])
    return feasibility_refusal(plan(0.0, REST, wp), JOINTS, settings, T1N, T2N, LIMIT)


def test_a_calm_move_is_feasible():
    assert _feasibility([1.0], [0.5]) == ''


def test_a_move_onto_the_soft_position_limit_is_refused():
    settings = GoalSettings(position_min_rad=-1.0, position_max_rad=1.0)
    assert _feasibility([2.0], [0.995], settings) == (
        'Trajectory cannot be followed: joint joint x1d 0.9928 rad at 1.875 s is outside the soft '
        'position limits [-1, 1] rad less a margin of 0.01 rad'
    )
    assert _feasibility([2.0], [0.985], settings) == ''


def test_a_move_beyond_the_velocity_share_is_refused():
    # rest to rest over 1 rad in 0.1 s: x1d' = 30 s^2 (1 - s)^2 rad / 0.1 s peaks at 18.75 rad/s;
    # the first grid point beyond 0.9 * 20 rad/s is s = 7/16 (18.17 rad/s)
    assert _feasibility([0.1], [1.0]) == (
        "Trajectory cannot be followed: joint joint x1d' 18.17 rad/s at 0.044 s is beyond 0.9 of "
        'the soft velocity limit 20 rad/s'
    )


def test_a_move_needing_more_than_half_the_current_is_refused_at_its_first_peak():
    # 0.1 rad in 50 ms: peak |x1d''| = 5.77 * 0.1 / 0.05^2 = 231 rad/s^2 -> 7.3 A < 10 A
    assert _feasibility([0.05], [0.1]) == ''
    # 0.2 rad in 50 ms: 462 rad/s^2 -> 14.7 A, beyond 0.5 of 20 A
    refusal = _feasibility([0.05], [0.2])
    assert refusal.startswith('Trajectory cannot be followed: joint joint nominal current ')
    assert refusal.endswith(
        "beyond 0.5 of the current limit 20 A (nominal current (x1d'' - theta2n x1d') / "
        'theta1n, eq. (3))'
    )


def test_goal_settings_refuse_an_empty_soft_position_window():
    with pytest.raises(ValueError, match='position_min_rad = 1.0 must be below position_max_rad'):
        GoalSettings(position_min_rad=1.0, position_max_rad=1.0)
