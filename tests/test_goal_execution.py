# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Goals sample by sample (actuator_controller.goal_execution): JTC's action behaviours, ROS-free.

A harness plays the assembly's part (the law samples the reference, the execution judges the
sample after it) with a joint that follows the desired angle exactly unless told otherwise;
the last tests close the loop on the simulated plant (actuator_sim.loop).
"""

import math

import numpy as np
import pytest

from actuator_controller.commanded_reference import CommandedReference
from actuator_controller.goal_execution import (
    ABORTED,
    BLOCKING,
    CANCELED,
    DEACTIVATED,
    GOAL_REACHED,
    GOAL_TOLERANCE_VIOLATED,
    INVALID_GOAL,
    OLD_HEADER_TIMESTAMP,
    PATH_TOLERANCE_VIOLATED,
    PREEMPTED,
    PREEMPTED_BY_TOPIC,
    STARTED,
    SUCCEEDED,
    Goal,
    GoalEvent,
    Mailbox,
    TrajectoryExecution,
)
from actuator_controller.trajectory import DesiredState, Waypoints
from actuator_controller.trajectory_settings import (
    JointConstraints,
    TrajectoryConstraints,
    TrajectorySettings,
)
from actuator_core import limits
from actuator_core.status import Status

MS = 1_000_000
DT = 1e-3
DYNAMICS = (limits.THETA1N, limits.THETA2N, limits.CURRENT_LIMIT_A)


class Harness:
    """The reference and the execution, driven one sample at a time like the assembly does."""

    def __init__(self, settings=None):
        self.settings = settings or TrajectorySettings(('joint',))
        self.reference = CommandedReference(self.settings.max_deceleration)
        self.execution = TrajectoryExecution(self.reference, self.settings, DYNAMICS)
        self.reference.restart_from(0.0)  # the assembly's first sample: hold the joint's angle
        self.k = 0
        self.events: list[GoalEvent] = []
        self.desired: list[tuple] = []

    def run(self, n, lag=lambda t: 0.0, status=Status.OK):
        """Run n samples; the joint is ``lag(t)`` behind the desired angle, at its velocity."""
        for _ in range(n):
            stamp, t = self.k * MS, self.k * DT
            if status in (Status.OK, Status.RECOVERING):
                ref = self.reference.sample(t)  # the law's sample
                self.desired.append(tuple(ref))
                y = ref.position_rad - lag(t)
                desired = DesiredState((ref[0],), (ref[1],), (ref[2],))
                self.execution.after_sample(stamp, status, t, desired, (y,), (ref[1],))
            else:
                self.execution.after_sample(stamp, status, None, None, (math.nan,), None)
            self.events += self.execution.take_events()
            self.k += 1
        return self

    def goal(self, goal_id, times, positions, start_ms=0, velocities=None, action=True, tol=None):
        wp = Waypoints(
            np.asarray(times, dtype=float),
            np.asarray(positions, dtype=float)[:, None],
            None if velocities is None else np.asarray(velocities, dtype=float)[:, None],
        )
        tolerances = tol or self.settings.default_tolerances()
        goal = Goal(goal_id, wp, tolerances, start_ms * MS, action)
        self.execution.submit(goal)
        return goal

    def kinds(self):
        return [(e.goal_id, e.kind) for e in self.events]


def test_a_single_point_goal_starts_at_once_and_succeeds_when_its_point_is_due():
    h = Harness()
    h.goal('a', [1.0], [0.5])
    h.run(1)
    assert h.events == [GoalEvent(0, 'a', STARTED, end_ns=1000 * MS)]
    h.run(500)
    feedback = h.execution.feedback
    assert feedback.goal_id == 'a' and feedback.stamp_ns == 500 * MS
    assert feedback.desired.positions[0] == pytest.approx(h.desired[-1][0])
    h.run(600)
    assert h.events[1] == GoalEvent(1000 * MS, 'a', SUCCEEDED, 0, GOAL_REACHED)
    assert h.desired[1000] == pytest.approx((0.5, 0.0, 0.0))
    assert h.execution.feedback is None and h.execution.active is None
    assert h.desired[-1] == pytest.approx((0.5, 0.0, 0.0))  # and holds its last point


def test_a_multi_point_goal_passes_each_point_when_it_is_due():
    h = Harness()
    h.goal('a', [0.2, 0.5, 0.8], [0.1, -0.2, 0.3])
    h.run(900)
    for k, p in ((200, 0.1), (500, -0.2), (800, 0.3)):
        assert h.desired[k][0] == pytest.approx(p, abs=1e-12)
    assert h.kinds() == [('a', STARTED), ('a', SUCCEEDED)]


def _steps(desired):
    """Largest sample-to-sample change of x1d, x1d', x1d''."""
    return np.max(np.abs(np.diff(np.array(desired), axis=0)), axis=0)


def test_a_new_goal_preempts_the_running_one_and_starts_from_its_desired_state():
    h = Harness()
    h.goal('a', [2.0], [1.0])
    h.run(700)
    h.goal('b', [0.5], [0.2])
    h.run(800)
    assert h.events[1:3] == [
        GoalEvent(700 * MS, 'a', ABORTED, INVALID_GOAL, PREEMPTED),
        GoalEvent(700 * MS, 'b', STARTED, end_ns=1200 * MS),
    ]
    assert h.events[3] == GoalEvent(1200 * MS, 'b', SUCCEEDED, 0, GOAL_REACHED)
    around = h.desired[695:710]
    # no step at the hand-over: each change within what the neighbouring samples show
    inside, before = _steps(around), _steps(h.desired[680:700])
    assert inside[0] < 1.2 * before[0] + 1e-4 and inside[1] < 0.1
    assert h.desired[1200][0] == pytest.approx(0.2, abs=1e-12)


def test_a_trajectory_on_the_topic_preempts_an_action_goal_with_its_own_string():
    h = Harness()
    h.goal('a', [1.0], [0.5])
    h.run(100)
    h.goal('topic-1', [0.5], [0.1], action=False)
    h.run(1)
    assert h.events[1] == GoalEvent(100 * MS, 'a', ABORTED, INVALID_GOAL, PREEMPTED_BY_TOPIC)
    h.run(10)
    assert h.execution.feedback is None  # nobody to send feedback to


def test_cancel_brings_the_desired_motion_to_rest_within_the_deceleration_bound():
    h = Harness()
    h.goal('a', [1.0], [1.0])  # rest to rest: 1.875 rad/s at 0.5 s
    h.run(500)
    h.execution.cancel('a')
    h.run(300)
    assert h.events[1] == GoalEvent(500 * MS, 'a', CANCELED)
    after = np.array(h.desired[500:])
    bound = limits.STOP_DECELERATION_RAD_S2
    assert np.max(np.abs(after[:, 2])) <= bound * (1 + 1e-6)
    assert after[-1, 1:] == pytest.approx((0.0, 0.0))  # at rest, and holds
    assert after[-1, 0] == pytest.approx(after[-100, 0])
    assert _steps(h.desired[495:510])[1] < 0.4  # no velocity step (the stop peaks at 0.31/ms)
    assert 0.5 < after[-1, 0] < 1.0  # stopped on the way: neither at the start nor the goal


def test_a_cancel_of_a_goal_that_has_not_started_drops_it_and_the_joint_keeps_holding():
    h = Harness()
    h.goal('a', [1.0], [1.0], start_ms=500)
    h.run(100)
    h.execution.cancel('a')
    h.run(1000)
    assert h.events == [GoalEvent(100 * MS, 'a', CANCELED)]
    assert h.desired[-1] == (0.0, 0.0, 0.0)


def test_a_goal_with_a_future_start_waits_for_its_sample_and_keeps_its_points_times():
    h = Harness()
    h.goal('a', [0.25, 0.5], [0.1, 0.2], start_ms=300)
    h.run(900)
    assert h.events[0] == GoalEvent(300 * MS, 'a', STARTED, end_ns=800 * MS)
    assert h.desired[299] == (0.0, 0.0, 0.0)  # held until then
    assert h.desired[550][0] == pytest.approx(0.1, abs=1e-12)
    assert h.desired[800][0] == pytest.approx(0.2, abs=1e-12)


def test_a_goal_taken_after_all_its_points_were_due_aborts_as_too_old():
    h = Harness()
    h.run(600)
    h.goal('a', [0.25], [0.1], start_ms=100)
    h.run(1)
    assert h.events == [
        GoalEvent(
            600 * MS,
            'a',
            ABORTED,
            OLD_HEADER_TIMESTAMP,
            'Every point of the trajectory was due before the sample it started at',
        )
    ]


def test_a_start_in_the_past_skips_the_points_already_due():
    h = Harness()
    h.run(400)
    h.goal('a', [0.2, 0.6], [0.3, 0.1], start_ms=100)  # first point due at 300 ms: passed
    h.run(400)
    assert h.events[0] == GoalEvent(400 * MS, 'a', STARTED, end_ns=700 * MS)
    assert h.desired[700][0] == pytest.approx(0.1, abs=1e-12)
    assert max(d[0] for d in h.desired) < 0.2  # never went to the skipped point


def _tolerances(path=0.0, goal=0.0, goal_time=0.0):
    return TrajectorySettings(
        ('joint',),
        constraints=TrajectoryConstraints(goal_time=goal_time),
        joints=(JointConstraints(trajectory=path, goal=goal),),
    )


def test_a_path_tolerance_violation_aborts_and_the_joint_holds_where_it_is():
    h = Harness(_tolerances(path=0.01))
    h.goal('a', [1.0], [0.5])
    h.run(1000, lag=lambda t: 0.02 if t >= 0.4 else 0.0)
    assert h.events[1] == GoalEvent(
        400 * MS,
        'a',
        ABORTED,
        PATH_TOLERANCE_VIOLATED,
        'Aborted due to path tolerance violation: joint joint position error 0.02 rad beyond '
        '0.01 rad',
    )
    stopped_at = h.desired[400][0] - 0.02  # the joint's angle then
    rest = np.array(h.desired[600:])
    assert rest[:, 1:] == pytest.approx(np.zeros((len(rest), 2)))
    # it came to rest from the joint's own state: the stop distance at its velocity, no further
    velocity = h.desired[400][1]
    stop = 1.5 * velocity / limits.STOP_DECELERATION_RAD_S2
    assert rest[0, 0] == pytest.approx(stopped_at + velocity * stop / 2.0, abs=1e-9)


def test_a_path_tolerance_erased_by_the_goal_is_not_checked():
    h = Harness(_tolerances(path=0.01))
    tolerances, _ = __import__(
        'actuator_controller.goal_rules', fromlist=['resolve_tolerances']
    ).resolve_tolerances(h.settings.default_tolerances(), ('joint',), [('joint', -1.0, 0, 0)])
    h.goal('a', [0.5], [0.5], tol=tolerances)
    h.run(400, lag=lambda t: 0.02 if 0.1 < t < 0.3 else 0.0)
    assert h.kinds() == [('a', STARTED)]


def test_outside_the_goal_tolerance_after_goal_time_aborts_with_the_lateness():
    h = Harness(_tolerances(goal=0.001, goal_time=0.1))
    h.goal('a', [0.5], [0.5])
    h.run(700, lag=lambda t: 0.005 if t > 0.45 else 0.0)
    assert h.events[1] == GoalEvent(
        601 * MS,
        'a',
        ABORTED,
        GOAL_TOLERANCE_VIOLATED,
        'Aborted due to goal_time_tolerance exceeding by 0.101000 seconds: joint joint position '
        'error 0.005 rad beyond 0.001 rad',
    )


def test_without_goal_time_a_goal_outside_its_tolerance_waits_and_succeeds_once_inside():
    h = Harness(_tolerances(goal=0.001))
    h.goal('a', [0.5], [0.5])
    h.run(2000, lag=lambda t: 0.005 if 0.45 < t < 1.7 else 0.0)
    assert h.events[1] == GoalEvent(1700 * MS, 'a', SUCCEEDED, 0, GOAL_REACHED)


def test_the_velocity_at_the_end_must_be_within_stopped_velocity_tolerance():
    settings = TrajectorySettings(
        ('joint',), constraints=TrajectoryConstraints(stopped_velocity_tolerance=0.01)
    )
    h = Harness(settings)
    h.goal('a', [0.5], [0.5])
    h.run(600)  # exact tracking: the joint is at rest when the point is due
    assert h.kinds() == [('a', STARTED), ('a', SUCCEEDED)]
    assert h.events[1].stamp_ns == 500 * MS


@pytest.mark.parametrize('status', [Status.RESYNC, Status.LATCHED, Status.CONFLICT])
def test_goals_abort_while_the_law_cannot_run_and_new_ones_are_blocked(status):
    h = Harness()
    h.goal('a', [1.0], [0.5])
    h.goal('b', [1.0], [0.5], start_ms=800)  # preempts a at once, waits for 800 ms
    h.run(100)
    h.run(2, status=status)
    why = f'Aborted: {BLOCKING[status]}'
    assert h.events[-1] == GoalEvent(100 * MS, 'b', ABORTED, INVALID_GOAL, why)
    assert h.execution.blocked == BLOCKING[status]
    h.goal('c', [1.0], [0.5])  # raced the goal thread's check: ends at the next safe sample
    h.run(1, status=status)
    assert h.events[-1] == GoalEvent(102 * MS, 'c', ABORTED, INVALID_GOAL, why)
    h.run(1, status=Status.RECOVERING)
    assert h.execution.blocked == ''


def test_a_short_stale_gap_neither_ends_nor_blocks_a_goal():
    h = Harness()
    h.goal('a', [0.5], [0.5])
    h.run(100)
    h.run(3, status=Status.STALE_MEASUREMENT)
    h.run(500)
    assert h.kinds() == [('a', STARTED), ('a', SUCCEEDED)]


def test_deactivation_aborts_running_and_waiting_goals_with_jtcs_string():
    h = Harness()
    h.goal('a', [1.0], [0.5])
    h.run(300)
    h.goal('b', [1.0], [0.5], start_ms=900)
    h.run(1)
    h.execution.deactivate(301 * MS)
    h.events += h.execution.take_events()
    assert h.events[-1] == GoalEvent(301 * MS, 'b', ABORTED, INVALID_GOAL, DEACTIVATED)
    assert h.execution.active is None and h.execution.pending is None
    assert not h.reference.moving or h.reference.program.is_stop  # the desired motion stops


def test_a_goal_whose_start_the_moving_state_cannot_follow_aborts_and_the_motion_goes_on():
    h = Harness()
    h.goal('a', [1.0], [1.0])
    h.run(500)  # 1.875 rad/s now
    h.goal('b', [0.001], [h.desired[-1][0] - 0.01])  # reverse within 1 ms: far beyond 10 A
    h.run(1)
    last = h.events[-1]
    assert (last.goal_id, last.kind, last.error_code) == ('b', ABORTED, INVALID_GOAL)
    assert last.error_string.startswith('Trajectory cannot be followed: joint joint ')
    h.run(600)
    assert h.desired[-1] == pytest.approx((1.0, 0.0, 0.0))  # a was preempted but its plan ran


def test_mailbox_hands_commands_over_in_order_once():
    box = Mailbox()
    assert not box.waiting
    box.post(('goal', 1))
    box.post(('cancel', 1))
    assert box.waiting
    assert box.take() == [('goal', 1), ('cancel', 1)]
    assert not box.waiting and box.take() == []


# --- closed on the simulated plant (the offline loop runs the same objects as the nodes) ---------


def _deep_sea_hold(duration_s):
    from actuator_sim.loop import ClosedLoop
    from actuator_sim.scenarios import paper_scenario

    return ClosedLoop(paper_scenario('hold', 'pp_nftsmc_eso', 'hold', 'deep_sea', duration_s))


def test_offline_goals_and_cancels_are_handed_over_before_their_sample_in_stamp_order():
    """ClosedLoop.submit_at / cancel_at: each before the first sample at or after its stamp.

    Two due at the same sample go in stamp order: the cancel stamped after the second goal's
    hand-over ends it there; stamped before, it would find no goal and the goal would run on.
    """
    loop = _deep_sea_hold(0.12)
    tolerances = loop.scenario.trajectory.default_tolerances()
    wp = Waypoints(np.array([1.0]), np.array([[0.5]]))
    loop.submit_at(20 * MS, Goal('a', wp, tolerances))
    loop.cancel_at(50 * MS + 700, 'b')  # due at 51 ms, after b's hand-over
    loop.submit_at(50 * MS + 300, Goal('b', wp, tolerances))  # due at 51 ms
    trace = loop.run()
    assert [(e.stamp_ns, e.goal_id, e.kind, e.error_string) for e in loop.goal_events] == [
        (20 * MS, 'a', STARTED, ''),
        (51 * MS, 'a', ABORTED, PREEMPTED),
        (51 * MS, 'b', CANCELED, ''),  # canceled before its first sample: it never started
    ]
    moving = trace['reference_velocity_rad_s'] != 0.0
    assert not moving[:21].any() and moving[21:52].all()  # a's motion from the sample after
    assert np.all(trace['reference_position_rad'][:21] == 0.0)
    assert np.all(np.diff(trace['reference_position_rad'][20:52]) > 0.0)
    assert loop.schedule == []


@pytest.mark.slow
def test_offline_hold_keeps_the_joint_still_against_the_deep_sea_disturbance():
    loop = _deep_sea_hold(1.0)
    trace = loop.run()
    assert np.all(trace['reference_position_rad'] == 0.0)
    assert np.max(np.abs(trace['measured_position_rad'])) < 1e-3
    assert np.max(np.abs(trace['current_a'])) < 0.5 * limits.CURRENT_LIMIT_A
    assert loop.goal_events == []


@pytest.mark.slow
def test_offline_cancel_at_peak_velocity_stops_without_a_sample_at_the_current_limit():
    loop = _deep_sea_hold(1.5)
    # rest to rest over 0.8 rad in 0.4 s from 0.1 s: peak 3.75 rad/s at 0.3 s
    wp = Waypoints(np.array([0.4]), np.array([[0.8]]))
    goal = Goal('a', wp, loop.scenario.trajectory.default_tolerances(), start_ns=100 * MS)
    loop.submit_at(0, goal)
    loop.cancel_at(300 * MS, 'a')
    trace = loop.run()
    assert [(e.stamp_ns, e.kind) for e in loop.goal_events] == [
        (100 * MS, STARTED),
        (300 * MS, CANCELED),
    ]
    after = trace['t_s'] > 0.3
    assert np.max(np.abs(trace['reference_acceleration_rad_s2'][after])) <= (
        limits.STOP_DECELERATION_RAD_S2 * (1 + 1e-6)
    )
    assert not np.any(trace['saturated'])
    assert np.max(np.abs(trace['error_rad'])) < 2e-3
    assert trace['reference_velocity_rad_s'][-1] == 0.0
    # the envelope runs on from the run's start (a goal starts from the desired state: no step
    # of e); e stays inside it, and the status says OK only where it does
    inside = (trace['error_rad'] > trace['lower_bound_rad']) & (
        trace['error_rad'] < trace['upper_bound_rad']
    )
    assert np.all(inside)
    assert np.all((trace['status'] == Status.OK) <= trace['bounds_kept'].astype(bool))


def test_a_resync_aborts_the_goal_and_the_reference_restarts_as_a_hold_of_the_joints_angle():
    """The assembly's restart hook: after the resync the joint holds the angle it is at."""
    from actuator_controller.laws import make_controller
    from actuator_core.assembly import RESYNC_SAMPLES, ControlSampleAssembly

    h = Harness()
    assembly = ControlSampleAssembly(make_controller('pp_nftsmc_eso'), h.reference, MS)
    angle = [0.0]

    def sample(k):
        stamp = k * MS
        assembly.add_measurement(stamp, angle[0])
        out = assembly.add_estimate(stamp, 0.0, 0.0)
        ref = out.reference
        desired = None if ref is None else DesiredState((ref[0],), (ref[1],), (ref[2],))
        h.execution.after_sample(stamp, out.status, out.t_s, desired, (angle[0],), (0.0,))
        h.events += h.execution.take_events()
        return out

    for k in range(10):
        sample(k)
    h.goal('a', [1.0], [0.4])
    for k in range(10, 200):
        sample(k)
    assert h.reference.moving
    assembly.resync(200 * MS)
    angle[0] = 0.123  # the braked joint came to rest here
    statuses = [sample(k).status for k in range(200, 200 + RESYNC_SAMPLES + 1)]
    assert statuses[0] == Status.RESYNC and statuses[-1] == Status.RECOVERING
    assert h.events[-1] == GoalEvent(
        200 * MS, 'a', ABORTED, INVALID_GOAL, f'Aborted: {BLOCKING[Status.RESYNC]}'
    )
    restarted = sample(200 + RESYNC_SAMPLES + 1)
    assert tuple(restarted.reference) == (0.123, 0.0, 0.0)
    assert h.execution.blocked == ''
