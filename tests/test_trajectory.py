# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Waypoints -> x1d, x1d', x1d'' (actuator_controller.trajectory): the math on its own."""

import numpy as np
import pytest

from actuator_controller.commanded_reference import CommandedReference
from actuator_controller.trajectory import (
    CUBIC,
    POSITIONS_ONLY,
    QUINTIC,
    DesiredState,
    Hold,
    Segments,
    Waypoints,
    _stop_peak,
    cubic_end_accelerations,
    plan,
    quintic_coefficients,
    stop_segment,
    three_point_derivatives,
)

DT = 1e-3
MOVING = DesiredState((0.3,), (-1.2,), (25.0,))


def _one(c, h):
    """Return a one-segment, one-joint Segments of coefficients ``c`` over [0, h]."""
    return Segments(np.array([0.0]), np.array([h]), np.asarray(c, dtype=float)[:, None, None])


def _state(segments, t):
    s = segments.sample(t)
    return np.array([s.positions[0], s.velocities[0], s.accelerations[0]])


def test_quintic_meets_position_velocity_and_acceleration_at_both_ends():
    rng = np.random.default_rng(3)
    for _ in range(20):
        p0, v0, a0, p1, v1, a1 = rng.normal(size=6) * [1, 3, 30, 1, 3, 30]
        h = rng.uniform(0.005, 2.0)
        seg = _one(quintic_coefficients(p0, v0, a0, p1, v1, a1, h), h)
        np.testing.assert_allclose(_state(seg, 0.0), [p0, v0, a0], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(_state(seg, h), [p1, v1, a1], rtol=1e-7, atol=1e-7)


def test_quintic_through_a_cubics_end_accelerations_is_that_cubic():
    p0, v0, p1, v1, h = 0.2, 1.0, -0.4, 0.5, 0.3
    a0, a1 = cubic_end_accelerations(p0, v0, p1, v1, h)
    c = quintic_coefficients(p0, v0, a0, p1, v1, a1, h)
    assert abs(c[4]) < 1e-9 and abs(c[5]) < 1e-9  # no quartic or quintic term left
    assert a0 != pytest.approx(a1)  # a genuine cubic: its acceleration changes along it


def test_three_point_derivatives_are_exact_for_a_parabola_on_an_uneven_grid():
    times = np.array([0.0, 0.1, 0.35, 0.4, 0.9])
    positions = (2.0 - 3.0 * times + 7.0 * times**2)[:, None]
    velocity, acceleration = three_point_derivatives(times, positions)
    np.testing.assert_allclose(velocity[:, 0], -3.0 + 14.0 * times[1:-1], rtol=1e-12)
    np.testing.assert_allclose(acceleration[:, 0], 14.0, rtol=1e-12)


def _waypoints(kind):
    times = np.array([0.05, 0.12, 0.2, 0.31])
    positions = np.array([[0.35], [0.5], [0.45], [0.6]])
    velocities = np.array([[2.0], [0.5], [-0.3], [0.0]]) if kind != POSITIONS_ONLY else None
    accelerations = np.array([[10.0], [-20.0], [5.0], [0.0]]) if kind == QUINTIC else None
    return Waypoints(times, positions, velocities, accelerations)


@pytest.mark.parametrize('kind', [POSITIONS_ONLY, CUBIC, QUINTIC])
def test_a_plan_starts_at_the_start_state_and_passes_every_point(kind):
    wp = _waypoints(kind)
    assert wp.kind == kind
    segments = plan(1.0, MOVING, wp)
    np.testing.assert_allclose(_state(segments, 1.0), [0.3, -1.2, 25.0], atol=1e-12)
    for i, t in enumerate(wp.times_s):
        p, v, a = _state(segments, 1.0 + t)
        assert p == pytest.approx(wp.positions[i, 0], abs=1e-9)
        if kind != POSITIONS_ONLY:
            assert v == pytest.approx(wp.velocities[i, 0], abs=1e-7)
        if kind == QUINTIC:
            assert a == pytest.approx(wp.accelerations[i, 0], abs=1e-5)
    assert segments.end_s == pytest.approx(1.31)
    p, v, a = _state(segments, 1.31)
    assert v == pytest.approx(0.0, abs=1e-7)  # at rest; a cubic's last acceleration is its own
    if kind != CUBIC:
        assert a == pytest.approx(0.0, abs=1e-5)


def _ends(segments, k):
    """(p, v, a) at the end of segment k - 1 and at the start of segment k, exactly."""
    c = segments.coefficients  # (segments, joints, 6)
    h = segments.durations[k - 1]
    powers = h ** np.arange(6)
    left = c[k - 1, 0]
    end = [
        left @ powers,
        left[1:] @ (np.arange(1, 6) * powers[:5]),
        left[2:] @ (np.arange(2, 6) * np.arange(1, 5) * powers[:4]),
    ]
    start = [c[k, 0, 0], c[k, 0, 1], 2.0 * c[k, 0, 2]]
    return np.array(end), np.array(start)


@pytest.mark.parametrize('kind', [POSITIONS_ONLY, QUINTIC])
def test_velocity_and_acceleration_are_continuous_at_every_knot(kind):
    segments = plan(0.0, MOVING, _waypoints(kind))
    for k in range(1, len(segments.starts)):
        end, start = _ends(segments, k)
        np.testing.assert_allclose(start, end, rtol=1e-9, atol=1e-9)


def test_cubic_points_keep_velocity_continuous_and_the_first_knot_smooth():
    segments = plan(0.0, MOVING, _waypoints(CUBIC))
    end, start = _ends(segments, 1)  # the first segment meets the first cubic's acceleration
    np.testing.assert_allclose(start, end, rtol=1e-9, atol=1e-9)
    end, start = _ends(segments, 2)
    assert start[:2] == pytest.approx(end[:2], abs=1e-9)  # position and velocity continuous
    assert abs(start[2] - end[2]) > 1.0  # acceleration steps between cubics (JTC's cubic)


def test_positions_only_points_of_a_smooth_motion_are_followed_closely():
    # sin at 10 ms points: the parabola's derivatives miss by O(h^2), the path by far less
    times = np.arange(1, 201) * 0.01
    segments = plan(
        0.0, DesiredState((0.0,), (1.0,), (0.0,)), Waypoints(times, np.sin(times)[:, None])
    )
    grid = np.arange(0.05, 1.9, DT)
    p = np.array([segments.sample(t).positions[0] for t in grid])
    v = np.array([segments.sample(t).velocities[0] for t in grid])
    assert np.max(np.abs(p - np.sin(grid))) < 2e-6
    assert np.max(np.abs(v - np.cos(grid))) < 5e-4


def test_waypoints_after_drop_the_points_already_due():
    wp = _waypoints(QUINTIC)
    ahead = wp.after(0.12)
    np.testing.assert_array_equal(ahead.times_s, [0.2, 0.31])
    assert ahead.kind == QUINTIC and ahead.positions.shape == (2, 1)


def test_a_plan_needs_a_point_ahead():
    with pytest.raises(ValueError, match='no waypoint ahead'):
        plan(0.0, MOVING, _waypoints(QUINTIC).after(1.0))


def _peak_acceleration(segments, joint=0):
    return max(
        abs(segments.sample(t).accelerations[joint])
        for t in np.linspace(*(segments.starts[0], segments.end_s), 2001)
    )


def test_a_stop_from_speed_takes_1_5_v_over_d_and_stops_halfway_down_a_constant_ramp():
    stop = stop_segment(2.0, DesiredState((0.1,), (8.8,), (0.0,)), (314.0,))
    duration = stop.end_s - 2.0
    assert duration == pytest.approx(1.5 * 8.8 / 314.0, rel=1e-9)
    assert _peak_acceleration(stop) == pytest.approx(314.0, rel=1e-4)
    p, v, a = _state(stop, stop.end_s)
    assert (v, a) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert p == pytest.approx(0.1 + 8.8 * duration / 2.0, rel=1e-9)
    np.testing.assert_allclose(_state(stop, 2.0), [0.1, 8.8, 0.0])  # no step at its start


def test_a_stop_is_the_shortest_within_the_bound_whatever_the_acceleration_it_starts_with():
    start = DesiredState((0.0,), (-3.0,), (-120.0,))  # still speeding up
    stop = stop_segment(0.0, start, (200.0,))
    assert _peak_acceleration(stop) == pytest.approx(200.0, rel=1e-4)
    assert _stop_peak(-3.0, -120.0, 0.97 * stop.end_s) > 200.0  # any shorter breaks the bound
    np.testing.assert_allclose(_state(stop, 0.0), [0.0, -3.0, -120.0], atol=1e-12)


def test_a_stop_that_starts_beyond_its_bound_keeps_to_the_acceleration_it_has():
    stop = stop_segment(0.0, DesiredState((0.0,), (1.0,), (500.0,)), (100.0,))
    assert _peak_acceleration(stop) == pytest.approx(500.0, rel=1e-3)


def test_joints_stop_together_each_within_its_own_bound():
    start = DesiredState((0.0, 1.0), (4.0, -1.0), (0.0, 0.0))
    stop = stop_segment(0.0, start, (400.0, 50.0))
    assert stop.end_s == pytest.approx(max(1.5 * 4.0 / 400.0, 1.5 * 1.0 / 50.0))
    assert _peak_acceleration(stop, 0) <= 400.0 * (1 + 1e-6)
    assert _peak_acceleration(stop, 1) == pytest.approx(50.0, rel=1e-4)
    assert stop.sample(stop.end_s).velocities == pytest.approx((0.0, 0.0), abs=1e-9)


def test_no_stop_from_rest():
    assert stop_segment(0.0, DesiredState((0.4,), (0.0,), (0.0,)), (100.0,)) is None


def test_hold_is_at_rest_at_its_angle_for_ever():
    hold = Hold(0.25)
    assert hold.sample(1e6) == DesiredState((0.25,), (0.0,), (0.0,))


def test_segment_grid_resolves_every_segment_alike_however_short():
    wp = Waypoints(np.array([0.0005, 0.5]), np.array([[0.31], [0.4]]))
    segments = plan(0.0, MOVING, wp)  # half a sample, then 499.5 ms
    t, p, v, a = segments.grid(points_per_segment=16)
    assert p.shape == v.shape == a.shape == (34, 1)
    np.testing.assert_allclose(t[:17], np.linspace(0.0, 0.0005, 17), atol=1e-15)
    np.testing.assert_allclose(t[17:], np.linspace(0.0005, 0.5, 17), atol=1e-15)
    k = 20
    np.testing.assert_allclose([p[k, 0], v[k, 0], a[k, 0]], _state(segments, t[k]), atol=1e-9)


def test_commanded_reference_holds_plans_and_comes_to_rest_after_a_moving_end():
    reference = CommandedReference((300.0,))
    reference.restart_from(0.5)
    assert reference.sample(3.0) == (0.5, 0.0, 0.0)
    wp = Waypoints(np.array([0.1]), np.array([[0.6]]), np.array([[1.0]]), np.array([[0.0]]))
    reference.follow(plan(3.0, reference.state(3.0), wp))
    assert reference.moving
    p, v, a = reference.sample(3.1)
    assert (p, v) == pytest.approx((0.6, 1.0))
    # past its end the plan gives way to a stop from (0.6, 1.0, 0) within 300 rad/s^2
    after = [reference.sample(3.1 + k * DT) for k in range(1, 40)]
    assert max(abs(s.acceleration_rad_s2) for s in after) <= 300.0 * (1 + 1e-6)
    assert reference.sample(4.0) == pytest.approx((0.6 + 1.0 * 0.005 / 2.0 * 1.0, 0.0, 0.0))
    assert not reference.moving
