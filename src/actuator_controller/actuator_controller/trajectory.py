# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Waypoints -> x1d and its first two derivatives on the sample grid (ROS-free).

A goal's points become quintic segments p(tau) = c0 + c1 tau + ... + c5 tau^5, each fixed by
position, velocity and acceleration at both its ends, so x1d, x1d' and x1d'' are continuous
wherever two segments meet: the PP-NFTSMC-ESO law feeds x1d'' into alpha' (33), and a jump
there is a jump of the current. What the knots' derivatives are depends on what the points
carry, as in joint_trajectory_controller:

* positions, velocities, accelerations: quintic through them (JTC's quintic);
* positions, velocities: the cubic through them (JTC's cubic): each segment's end
  accelerations are its cubic's, so x1d'' may step at a knot (x1d' does not);
* positions only: JTC interpolates linearly (x1d' steps at every knot). Here each inner knot
  gets the velocity and acceleration of the parabola through it and its two neighbours (three
  point differences, second order on an even grid), the last knot rest (0, 0): continuous in
  velocity and acceleration; the cost against quintic points is what those differences miss
  (benchmarked by ``actuator_bench.goal_bench``).

The first segment always runs from the desired state at the sample the goal starts at
(position, velocity and acceleration the law used there) to the first point still ahead, so
a goal started from hold, or one replacing a moving goal, causes no step in x1d, x1d' or
x1d''. ``stop_segment`` brings a moving desired state to rest within a bounded deceleration
(a cancel, an abort); ``Hold`` keeps one angle.

Times are seconds on the controller's reference clock (the assembly's t); every array is
(points or segments, joints).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import NamedTuple, Optional, Sequence

import numpy as np

#: What the points of a goal carry, as JTC names its interpolation by them.
POSITIONS_ONLY = 'positions'
CUBIC = 'positions+velocities'
QUINTIC = 'positions+velocities+accelerations'
#: Iterations of the bisection for a stop's duration (relative width 2^-40 of the bracket).
STOP_BISECTIONS = 40
#: Below these a desired state is at rest (a plan's polynomial ends there to rounding).
REST_VELOCITY_RAD_S = 1e-12
REST_ACCELERATION_RAD_S2 = 1e-9


class DesiredState(NamedTuple):
    """Position [rad], velocity [rad/s] and acceleration [rad/s^2] of every joint."""

    positions: tuple
    velocities: tuple
    accelerations: tuple


@dataclass(frozen=True)
class Waypoints:
    """A goal's points: times [s] after the goal's start, positions and what else they carry.

    ``velocities``/``accelerations`` are None when the points do not carry them.
    """

    times_s: np.ndarray  #: (n,) strictly increasing, the first > 0 (earlier ones are dropped)
    positions: np.ndarray  #: (n, joints) [rad]
    velocities: Optional[np.ndarray] = None  #: (n, joints) [rad/s]
    accelerations: Optional[np.ndarray] = None  #: (n, joints) [rad/s^2]

    @property
    def kind(self) -> str:
        """POSITIONS_ONLY, CUBIC or QUINTIC."""
        if self.velocities is None:
            return POSITIONS_ONLY
        return CUBIC if self.accelerations is None else QUINTIC

    def after(self, elapsed_s: float) -> Waypoints:
        """Return the points later than ``elapsed_s`` after the start (those still ahead)."""
        keep = self.times_s > elapsed_s
        return Waypoints(
            self.times_s[keep],
            self.positions[keep],
            None if self.velocities is None else self.velocities[keep],
            None if self.accelerations is None else self.accelerations[keep],
        )


def quintic_coefficients(p0, v0, a0, p1, v1, a1, h):
    """c0..c5 of the quintic with (p, v, a) = (p0, v0, a0) at 0 and (p1, v1, a1) at h.

    Elementwise over arrays; returns an array of shape (6,) + broadcast shape.
    """
    d = p1 - p0
    h2 = h * h
    c3 = (20.0 * d - (8.0 * v1 + 12.0 * v0) * h - (3.0 * a0 - a1) * h2) / (2.0 * h2 * h)
    c4 = (-30.0 * d + (14.0 * v1 + 16.0 * v0) * h + (3.0 * a0 - 2.0 * a1) * h2) / (2.0 * h2 * h2)
    c5 = (12.0 * d - 6.0 * (v1 + v0) * h + (a1 - a0) * h2) / (2.0 * h2 * h2 * h)
    return np.array(np.broadcast_arrays(p0, v0, 0.5 * a0, c3, c4, c5), dtype=float)


def cubic_end_accelerations(p0, v0, p1, v1, h) -> tuple:
    """(a0, a1): the accelerations at both ends of the cubic through (p0, v0) and (p1, v1)."""
    c2 = (3.0 * (p1 - p0) / h - 2.0 * v0 - v1) / h
    c3 = (2.0 * (p0 - p1) / h + v0 + v1) / (h * h)
    return 2.0 * c2, 2.0 * c2 + 6.0 * c3 * h


def three_point_derivatives(times, positions) -> tuple:
    """Velocity and acceleration at each inner knot of the parabola through it and its neighbours.

    ``times`` (n,), ``positions`` (n, joints), n >= 3; returns two (n - 2, joints) arrays.
    """
    h0 = (times[1:-1] - times[:-2])[:, None]
    h1 = (times[2:] - times[1:-1])[:, None]
    slope0 = (positions[1:-1] - positions[:-2]) / h0
    slope1 = (positions[2:] - positions[1:-1]) / h1
    velocity = (h1 * slope0 + h0 * slope1) / (h0 + h1)
    acceleration = 2.0 * (slope1 - slope0) / (h0 + h1)
    return velocity, acceleration


class Segments:
    """Quintic segments back to back: sample(t) gives every joint's (p, v, a) at t."""

    def __init__(self, starts_s: np.ndarray, durations_s: np.ndarray, coefficients: np.ndarray):
        """``coefficients``: (6, segments, joints), c_k of tau^k with tau from each start."""
        self.starts = np.asarray(starts_s, dtype=float).tolist()
        self.durations = np.asarray(durations_s, dtype=float).tolist()
        self.end_s = self.starts[-1] + self.durations[-1]
        self.coefficients = np.ascontiguousarray(np.moveaxis(coefficients, 0, -1))  # (s, j, 6)
        # The segment being sampled as Python floats: the node samples one point per period,
        # where numpy's per-call overhead would cost more than the polynomial. Converted when
        # entered, so a goal of many points costs its start nothing per point.
        self._cursor = -1
        self._current: list = []
        self.is_stop = False  #: a stop (``stop_segment``): a hold follows it

    def _enter(self, t: float) -> int:
        """Make the segment holding t current (the last beyond the end, the first before)."""
        k = self._cursor
        starts = self.starts
        if k < 0 or not (starts[k] <= t and (k + 1 == len(starts) or t < starts[k + 1])):
            k = max(0, bisect.bisect_right(starts, t) - 1)
            self._cursor = k
            self._current = self.coefficients[k].tolist()
        return k

    def sample(self, t: float) -> DesiredState:
        """Every joint's position, velocity and acceleration at t [s] (clamped to the span)."""
        k = self._enter(t)
        tau = min(max(t - self.starts[k], 0.0), self.durations[k])
        p, v, a = [], [], []
        for c0, c1, c2, c3, c4, c5 in self._current:
            p.append(c0 + tau * (c1 + tau * (c2 + tau * (c3 + tau * (c4 + tau * c5)))))
            v.append(c1 + tau * (2.0 * c2 + tau * (3.0 * c3 + tau * (4.0 * c4 + tau * 5.0 * c5))))
            a.append(2.0 * c2 + tau * (6.0 * c3 + tau * (12.0 * c4 + tau * 20.0 * c5)))
        return DesiredState(tuple(p), tuple(v), tuple(a))

    def head(self, count: int) -> Segments:
        """Return the first ``count`` segments (all, when there are fewer)."""
        n = min(count, len(self.starts))
        return Segments(
            np.array(self.starts[:n]),
            np.array(self.durations[:n]),
            np.moveaxis(self.coefficients[:n], -1, 0),
        )

    def grid(self, points_per_segment: int = 16) -> tuple:
        """(t, p, v, a) on every segment's ends and ``points_per_segment`` - 1 points inside.

        Evenly within each segment whatever its length: a quintic's x1d'' is a cubic, whose
        extremes this resolves (what the feasibility checks of ``goal_rules`` judge), also in a
        segment shorter than a sample, where the law would see the jump between two samples.
        Arrays (m,) and (m, joints).
        """
        fractions = np.linspace(0.0, 1.0, points_per_segment + 1)
        durations = np.asarray(self.durations)
        tau = (durations[:, None] * fractions[None, :]).reshape(-1, 1)  # segment by segment
        c = np.repeat(self.coefficients, fractions.size, axis=0)  # (m, joints, 6)
        c0, c1, c2, c3, c4, c5 = (c[..., k] for k in range(6))
        p = c0 + tau * (c1 + tau * (c2 + tau * (c3 + tau * (c4 + tau * c5))))
        v = c1 + tau * (2.0 * c2 + tau * (3.0 * c3 + tau * (4.0 * c4 + tau * 5.0 * c5)))
        a = 2.0 * c2 + tau * (6.0 * c3 + tau * (12.0 * c4 + tau * 20.0 * c5))
        t = np.repeat(np.asarray(self.starts), fractions.size) + tau[:, 0]
        return t, p, v, a


def plan(start_s: float, start: DesiredState, waypoints: Waypoints) -> Segments:
    """Segments from ``start`` (the desired state at ``start_s``) through every waypoint.

    ``waypoints.times_s`` count from ``start_s`` and must all be after it (``Waypoints.after``).
    The last knot is at rest unless its points carry a velocity (and acceleration).
    """
    n = len(waypoints.times_s)
    if n == 0:
        raise ValueError('no waypoint ahead of the start')
    times = np.concatenate(([0.0], np.asarray(waypoints.times_s, dtype=float)))
    p = np.vstack([np.asarray(start.positions, dtype=float), waypoints.positions])
    joints = p.shape[1]
    v = np.zeros((n + 1, joints))
    a = np.zeros((n + 1, joints))
    v[0], a[0] = start.velocities, start.accelerations
    kind = waypoints.kind
    if kind == POSITIONS_ONLY:
        if n >= 2:
            v[1:-1], a[1:-1] = three_point_derivatives(times, p)
    else:
        v[1:] = waypoints.velocities
        if kind == QUINTIC:
            a[1:] = waypoints.accelerations
    h = np.diff(times)[:, None]
    a_start, a_end = a[:-1].copy(), a[1:].copy()
    if kind == CUBIC and n >= 2:  # the cubics between the points; the first segment stays quintic
        cubic0, cubic1 = cubic_end_accelerations(p[1:-1], v[1:-1], p[2:], v[2:], h[1:])
        a_start[1:], a_end[1:] = cubic0, cubic1
        a_end[0] = cubic0[0]  # the first segment meets the first cubic's acceleration
    coefficients = quintic_coefficients(p[:-1], v[:-1], a_start, p[1:], v[1:], a_end, h)
    return Segments(start_s + times[:-1], h[:, 0], coefficients)


def stop_segment(
    start_s: float, start: DesiredState, max_deceleration: Sequence[float]
) -> Optional[Segments]:
    """Bring ``start`` to rest with |x1d''| within each joint's ``max_deceleration`` [rad/s^2].

    Each joint's velocity follows the cubic from (v0, a0) to (0, 0) over one duration T (the
    slowest joint's, so all stop together), so x1d'' stays continuous; T is the shortest for
    which no joint's |x1d''| exceeds its bound (or its own |a0|, when it starts beyond it).
    None when already at rest (hold it).
    """
    v0 = np.asarray(start.velocities, dtype=float)
    a0 = np.asarray(start.accelerations, dtype=float)
    if np.all(np.abs(v0) < REST_VELOCITY_RAD_S) and np.all(np.abs(a0) < REST_ACCELERATION_RAD_S2):
        return None
    bound = np.maximum(np.asarray(max_deceleration, dtype=float), np.abs(a0) * (1.0 + 1e-9))
    duration = max(_stop_duration(float(v), float(a), float(b)) for v, a, b in zip(v0, a0, bound))
    # position is the integral of v(s) = v0 (2s^3 - 3s^2 + 1) + a0 T (s^3 - 2s^2 + s), s = tau/T
    p0 = np.asarray(start.positions, dtype=float)
    t = duration
    c = np.array(
        [
            p0,
            v0,
            0.5 * a0,
            (-3.0 * v0 / t - 2.0 * a0) / (3.0 * t),
            (2.0 * v0 / t + a0) / (4.0 * t * t),
            np.zeros_like(p0),
        ]
    )
    stop = Segments(np.array([start_s]), np.array([duration]), c[:, None, :])
    stop.is_stop = True
    return stop


def _stop_peak(v0: float, a0: float, duration: float) -> float:
    """Largest |x1d''| of the stop cubic of duration T: at s = 0, 1 or the parabola's vertex."""
    q = 6.0 * v0 / duration + 3.0 * a0  # x1d''(s) = q s^2 - (q + a0) s + a0
    peak = abs(a0)
    if q != 0.0:
        s = (q + a0) / (2.0 * q)
        if 0.0 < s < 1.0:
            peak = max(peak, abs(q * s * s - (q + a0) * s + a0))
    return peak


def _stop_duration(v0: float, a0: float, bound: float) -> float:
    """Shortest T [s] whose stop cubic keeps |x1d''| within ``bound`` (bisection)."""
    if v0 == 0.0 and a0 == 0.0:
        return 0.0
    high = max(1.5 * abs(v0) / bound, 1e-6)
    while _stop_peak(v0, a0, high) > bound:
        high *= 2.0
    low = 0.0
    for _ in range(STOP_BISECTIONS):
        middle = 0.5 * (low + high)
        if middle > 0.0 and _stop_peak(v0, a0, middle) <= bound:
            high = middle
        else:
            low = middle
    return high


class Hold:
    """Every joint at rest at ``positions`` [rad]."""

    def __init__(self, positions) -> None:
        """Hold these angles (a scalar or a batch array keeps its type: the offline loop's)."""
        self.positions = tuple(positions) if isinstance(positions, (list, tuple)) else (positions,)
        zero = tuple(0.0 * p for p in self.positions)
        self.state = DesiredState(self.positions, zero, zero)
        self.end_s = float('-inf')

    def sample(self, t: float) -> DesiredState:
        """Return the held state, whatever t."""
        return self.state
