# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Commanding the running joint as ROS users do: JTC's action tests, ported to the nodes.

The loop (simulated plant, ESO, controller on the hold scenario) runs as separate processes on
an isolated domain; the test is an rclpy ActionClient (actuator_controller.goal_client). In sim
time (lockstep) and in real time. Where the real ros2cli is built, ``ros2 action send_goal``
drives the joint.
"""

import importlib.util
import shutil
import subprocess
import time

import numpy as np
import pytest

import ros_helpers
from host_probe import RERUN_STALL_MS, skip_or_fail

pytestmark = pytest.mark.ros

SCENARIO = 'hold_pp_nftsmc_eso'
JOINTS = ['joint']
#: Wall time a goal of about a second may take in the sim lockstep on a loaded 2-core machine.
GOAL_TIMEOUT_S = 60.0


class Client(ros_helpers.TestNode):
    """The test's node with a GoalClient; spins until runs end.

    In real time (``window``: the host probe's) a goal the controller refused or aborted because
    it was resynchronising ends the test through ``skip_or_fail``: a stall of the host makes the
    loop resync, and that refusal is the stated behaviour; without a stall the probe saw, it fails.
    """

    def __init__(self, context, window=None):
        from actuator_controller.goal_client import GoalClient

        super().__init__(context, 'goal_test_client')
        self.window = window
        self.goals = GoalClient(self.node)
        assert self.goals.action.wait_for_server(timeout_sec=30.0), 'no action server'

    def wait_steady(self, samples=100, timeout=180.0):
        """Wait for ``samples`` controlled samples in a row (past start-up's waiting and resync).

        A goal taken while the controller resynchronises aborts (goal_execution): the tests
        start on a loop that controls. The first loop of a session starts slowly (its processes
        compile their modules).
        """
        from actuator_core.status import Status
        from actuator_msgs.msg import ControllerState
        from actuator_ros.qos import control_qos

        streak = [0]

        def count(msg):
            streak[0] = streak[0] + 1 if msg.status in (Status.OK, Status.RECOVERING) else 0

        sub = self.node.create_subscription(
            ControllerState, 'controller/state', count, control_qos('realtime')
        )
        try:
            self.wait_for(lambda: streak[0] >= samples, timeout, 'a loop that controls')
        finally:
            self.node.destroy_subscription(sub)

    def send(self, goal, wait_answer=True):
        run = self.goals.send(goal)
        if wait_answer:
            self.wait_for(lambda: run.accepted is not None, 20.0, 'the goal answered')
            if run.accepted is False and self.window is not None:
                self.event(lambda e: e.event == 0, 'the refusal')
                newest = [e for e in self.goals.events if e.event == 0][-1]
                self._resync_ended(newest.error_string)
        return run

    def finish(self, run, timeout=GOAL_TIMEOUT_S):
        self.wait_for(lambda: run.done, timeout, 'the goal ended')
        if run.result is not None:
            self._resync_ended(run.result.error_string)
        return run

    def wait_moving(self, run, samples):
        """Wait for ``samples`` feedback messages of ``run`` (or its end, which finish judges)."""
        self.wait_for(
            lambda: len(run.feedback) >= samples or run.done, GOAL_TIMEOUT_S, 'the goal moving'
        )
        if run.done:
            self.finish(run)

    def _resync_ended(self, reason):
        """In real time, end the test by the host's evidence when a resync ended the goal."""
        from actuator_controller.goal_execution import BLOCKING
        from actuator_core.status import Status

        if self.window is not None and reason.endswith(BLOCKING[Status.RESYNC]):
            skip_or_fail(
                self.window, f'a goal ended by a resync: {reason}', stall_ms=RERUN_STALL_MS
            )

    def event(self, predicate, what, timeout=20.0):
        self.wait_for(lambda: any(predicate(e) for e in self.goals.events), timeout, what)
        return next(e for e in self.goals.events if predicate(e))


def _loop(ros_process, mode, extra=(), scenario=SCENARIO):
    """Start the loop on the hold scenario (real time: SCHED_FIFO 50 where granted)."""
    from actuator_bringup.run_description import closed_loop
    from actuator_bringup.runner import scenario_file

    specs = closed_loop(mode, 0.0, record=False, thread_priority=50 if mode == 'realtime' else 0)
    return ros_helpers.start_closed_loop(
        ros_process, specs, scenario_file(scenario), {'controller': list(extra)}
    )


def _client(rclpy_context, ros_process, mode='sim', scenario=SCENARIO, window=None):
    """Start the loop, wait until it controls, return a client of its controller."""
    _loop(ros_process, mode, scenario=scenario)
    client = Client(rclpy_context, window)
    client.wait_steady()
    return client


@pytest.fixture(
    params=['sim', pytest.param('realtime', marks=pytest.mark.realtime)],
)
def commanded(request, rclpy_context, ros_process):
    """(client, mode): the loop running on the hold scenario, and a client of its controller.

    Real time is timing-dependent on a shared host (a stall beyond the drive's timeout makes the
    controller resynchronise, and a running goal aborts then): marked realtime.
    """
    window = request.getfixturevalue('host_window') if request.param == 'realtime' else None
    client = _client(rclpy_context, ros_process, request.param, window=window)
    yield client, request.param
    client.node.destroy_node()


def _goal(times, positions, **kwargs):
    from actuator_controller.goal_client import follow_goal, joint_trajectory

    stamp_ns = kwargs.pop('stamp_ns', 0)
    velocities = kwargs.pop('velocities', None)
    return follow_goal(
        joint_trajectory(
            JOINTS,
            times,
            [[p] for p in positions],
            None if velocities is None else [[v] for v in velocities],
            stamp_ns=stamp_ns,
        ),
        **kwargs,
    )


def _kinds(client, goal_id):
    from actuator_msgs.msg import GoalEvent

    names = {v: k[len('EVENT_') :] for k, v in vars(GoalEvent).items() if k.startswith('EVENT_')}
    return [names[e.event] for e in client.goals.events_of(goal_id)]


def test_single_point_goal_succeeds_with_feedback(commanded):
    from actuator_controller.goal_client import goal_id

    client, mode = commanded
    run = client.finish(client.send(_goal([0.5], [0.2])))
    assert run.succeeded, (run.status, run.result)
    assert (run.result.error_code, run.result.error_string) == (0, 'Goal successfully reached!')
    assert run.feedback, 'no feedback while it ran'
    last = run.feedback[-1]
    assert list(last.joint_names) == JOINTS
    assert 0.0 < last.desired.positions[0] <= 0.2 + 1e-12
    assert abs(last.error.positions[0]) < 5e-3
    client.event(lambda e: e.goal_id == goal_id(run) and e.event == 3, 'SUCCEEDED event')
    assert _kinds(client, goal_id(run)) == ['ACCEPTED', 'STARTED', 'SUCCEEDED']


def test_multi_point_goal_passes_its_points_and_ends_when_the_last_is_due(commanded):
    from actuator_controller.goal_client import goal_id
    from actuator_core.timing import stamp_to_ns

    client, mode = commanded
    run = client.finish(client.send(_goal([0.3, 0.6, 0.9], [0.1, -0.1, 0.05])))
    assert run.succeeded, (run.status, run.result)
    started = client.event(lambda e: e.goal_id == goal_id(run) and e.event == 2, 'STARTED')
    ended = client.event(lambda e: e.goal_id == goal_id(run) and e.event == 3, 'SUCCEEDED')
    start_ns, end_ns = stamp_to_ns(started.header.stamp), stamp_to_ns(started.end)
    assert end_ns - start_ns == 900_000_000  # due 0.9 s after the sample it started at
    assert end_ns <= stamp_to_ns(ended.header.stamp) < end_ns + 50_000_000


def test_a_new_goal_replaces_the_running_one(commanded):
    from actuator_controller.goal_client import goal_id

    client, mode = commanded
    first = client.send(_goal([1.5], [0.4]))
    client.wait_moving(first, 3)
    second = client.finish(client.send(_goal([0.4], [-0.1])))
    client.finish(first)
    assert (first.result.error_code, first.result.error_string) == (
        -1,
        'Current goal preempted by new incoming action.',
    )
    assert first.status == 6  # ABORTED
    assert second.succeeded
    aborted = client.event(lambda e: e.goal_id == goal_id(first) and e.event == 4, 'ABORTED')
    started = client.event(lambda e: e.goal_id == goal_id(second) and e.event == 2, 'STARTED')
    assert aborted.header.stamp == started.header.stamp  # handed over at one sample


def test_cancel_brings_the_joint_to_rest_and_reports_canceled(commanded):
    client, mode = commanded
    run = client.send(_goal([2.0], [0.6]))
    client.wait_moving(run, 5)
    start = run.feedback[0].desired.positions[0]  # the angle held before (near 0 in real time)
    cancel = client.goals.cancel(run)
    client.wait_for(cancel.done, 20.0, 'the cancel answered')
    assert len(cancel.result().goals_canceling) == 1
    client.finish(run)
    assert run.status == 5  # CANCELED
    moved = run.feedback[-1].desired.positions[0]
    assert start < moved < 0.6  # stopped on its way


def test_path_tolerance_violation_aborts(commanded):
    client, mode = commanded
    # a path tolerance far below the tracking error of a move: the first sample beyond it ends it
    run = client.finish(client.send(_goal([1.0], [0.5], path_tolerance=[('joint', 1e-7, 0, 0)])))
    assert run.status == 6
    assert run.result.error_code == -4  # PATH_TOLERANCE_VIOLATED
    assert run.result.error_string.startswith(
        'Aborted due to path tolerance violation: joint joint position error '
    )
    assert run.result.error_string.endswith(' rad beyond 1e-07 rad')


def test_goal_tolerance_violation_aborts_after_goal_time(commanded):
    client, mode = commanded
    goal = _goal([0.3], [0.1], goal_tolerance=[('joint', 1e-12, 0, 0)], goal_time_tolerance_s=0.02)
    run = client.finish(client.send(goal))
    assert run.status == 6
    assert run.result.error_code == -5  # GOAL_TOLERANCE_VIOLATED
    assert run.result.error_string.startswith('Aborted due to goal_time_tolerance exceeding by ')
    assert ' seconds: joint joint position error ' in run.result.error_string


@pytest.mark.parametrize(
    'kwargs, expected',
    [
        (
            {'names': ['elbow']},
            "Incoming joint elbow doesn't match the controller's joints.",
        ),
        (
            {'times': [0.5, 0.5], 'positions': [0.1, 0.2]},
            'Time between points 0 and 1 is not strictly increasing, it is 0.500000 and '
            '0.500000 respectively',
        ),
        (
            {'velocities': [0.3]},
            'Velocity of last trajectory point of joint joint is not zero: 0.300000000000000',
        ),
        ({'times': [], 'positions': []}, 'Empty trajectory received.'),
        (
            {'path_tolerance': [('joint', -2.0, 0, 0)]},
            "joint 'joint' specified in goal.path_tolerance has an invalid position tolerance: "
            '-2.000000 (0: the default, -1: none, else > 0)',
        ),
    ],
)
def test_rejected_goals_get_no_result_and_their_reason_is_published(
    rclpy_context, ros_process, kwargs, expected
):
    from actuator_controller.goal_client import follow_goal, joint_trajectory

    client = _client(rclpy_context, ros_process)
    times, positions = kwargs.pop('times', [0.5]), kwargs.pop('positions', [0.2])
    velocities = kwargs.pop('velocities', None)
    names = kwargs.pop('names', JOINTS)
    trajectory = joint_trajectory(
        names,
        times,
        [[p] for p in positions],
        None if velocities is None else [[v] for v in velocities],
    )
    run = client.send(follow_goal(trajectory, **kwargs))
    assert run.accepted is False
    refused = client.event(lambda e: e.event == 0, 'the refusal')
    assert refused.error_string == expected
    assert refused.goal_id.startswith('refused-') and refused.from_action


def test_a_goal_with_multi_dof_joints_is_rejected_not_ignored(rclpy_context, ros_process):
    from actuator_controller.goal_interface import MULTI_DOF_REFUSED

    client = _client(rclpy_context, ros_process)
    goal = _goal([0.5], [0.2])
    goal.multi_dof_trajectory.joint_names = ['base']
    assert client.send(goal).accepted is False
    refused = client.event(lambda e: e.event == 0, 'the refusal')
    assert refused.error_string == MULTI_DOF_REFUSED


def test_a_goal_the_joint_cannot_follow_is_rejected_saying_which_check(rclpy_context, ros_process):
    client = _client(rclpy_context, ros_process)
    run = client.send(_goal([0.05], [0.5]))  # 0.5 rad in 50 ms: 18 rad/s, far beyond 10 A
    assert run.accepted is False
    refused = client.event(lambda e: e.event == 0, 'the refusal')
    assert refused.error_string.startswith('Trajectory cannot be followed: joint joint ')


def test_a_run_on_a_built_in_trajectory_refuses_goals_saying_why(rclpy_context, ros_process):
    client = _client(rclpy_context, ros_process, scenario='case2_pp_nftsmc_eso')
    run = client.send(_goal([0.5], [0.2]))
    assert run.accepted is False
    refused = client.event(lambda e: e.event == 0, 'the refusal')
    assert refused.error_string == (
        "the controller follows its built-in 'fast' reference (parameter reference): it takes "
        "goals with reference 'hold'"
    )


def test_a_future_start_time_starts_at_that_sample(rclpy_context, ros_process):
    from rosgraph_msgs.msg import Clock

    from actuator_controller.goal_client import goal_id
    from actuator_core.timing import stamp_to_ns

    client = _client(rclpy_context, ros_process)
    clock = []
    sub = client.node.create_subscription(Clock, '/clock', lambda m: clock.append(m.clock), 10)
    client.wait_for(lambda: clock, 20.0, '/clock')
    client.node.destroy_subscription(sub)
    start_ns = (stamp_to_ns(clock[-1]) // 1_000_000 + 1500) * 1_000_000  # 1.5 s ahead, on the grid
    run = client.finish(client.send(_goal([0.3], [0.1], stamp_ns=start_ns)))
    assert run.succeeded
    started = client.event(lambda e: e.goal_id == goal_id(run) and e.event == 2, 'STARTED')
    assert stamp_to_ns(started.header.stamp) == start_ns
    assert stamp_to_ns(started.end) == start_ns + 300_000_000


def test_goals_while_inactive_are_rejected_and_deactivation_aborts_the_running_one(
    rclpy_context, ros_process
):
    from actuator_controller.goal_rules import NOT_RUNNING

    client = _client(rclpy_context, ros_process)
    run = client.send(_goal([3.0], [0.5]))
    client.wait_for(lambda: len(run.feedback) >= 2, GOAL_TIMEOUT_S, 'the goal moving')
    assert client.transition('actuator_controller', 'deactivate')
    client.finish(run, 20.0)
    assert run.status == 6
    assert (run.result.error_code, run.result.error_string) == (
        -1,
        'Current goal cancelled during deactivate transition.',
    )
    late = client.send(_goal([0.5], [0.1]))
    assert late.accepted is False
    refused = client.event(lambda e: e.event == 0, 'the refusal')
    assert refused.error_string == NOT_RUNNING


def test_the_topic_moves_the_joint_and_an_empty_trajectory_on_it_changes_nothing(
    rclpy_context, ros_process
):
    from actuator_controller.goal_client import joint_trajectory
    from actuator_controller.goal_rules import EMPTY_TRAJECTORY

    client = _client(rclpy_context, ros_process)
    client.wait_matched(client.goals.topic)
    client.goals.publish(joint_trajectory(JOINTS, [0.8], [[0.3]]))
    started = client.event(lambda e: e.goal_id == 'topic-1' and e.event == 2, 'topic-1 started')
    client.goals.publish(joint_trajectory(JOINTS, [], []))
    refused = client.event(lambda e: e.goal_id == 'topic-2', 'topic-2 refused')
    assert (refused.event, refused.error_string) == (0, EMPTY_TRAJECTORY)
    ended = client.event(lambda e: e.goal_id == 'topic-1' and e.event == 3, 'topic-1 ended')
    assert not refused.from_action and not started.from_action
    assert ended.error_string == 'Goal successfully reached!'  # the empty one did not stop it


HAVE_ACTION_CLI = (
    shutil.which('ros2') is not None and importlib.util.find_spec('ros2action') is not None
)


@pytest.mark.skipif(
    not HAVE_ACTION_CLI,
    reason='ros2cli (ros2action) is not installed (not on PyPI): a Jazzy install or a checkout '
    'prepared as ../shared/real-ros2-tools.md says',
)
def test_ros2_action_send_goal_drives_the_joint(ros_env, rclpy_context, ros_process):
    _client(rclpy_context, ros_process)
    goal = (
        '{trajectory: {joint_names: [joint], points: [{positions: [0.25], '
        'time_from_start: {sec: 1}}]}}'
    )
    deadline = time.monotonic() + 30.0
    while True:  # the server appears once the controller is configured
        result = subprocess.run(
            [
                'ros2',
                'action',
                'send_goal',
                '/actuator_controller/follow_joint_trajectory',
                'control_msgs/action/FollowJointTrajectory',
                goal,
            ],
            env=ros_env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        if 'Goal accepted' in result.stdout or time.monotonic() > deadline:
            break
        time.sleep(1.0)
    assert 'Goal accepted' in result.stdout, result.stdout + result.stderr
    assert 'Goal finished with status: SUCCEEDED' in result.stdout, result.stdout
    assert 'Goal successfully reached!' in result.stdout


def test_a_commanded_sim_run_equals_the_offline_loop_bit_for_bit(isolated):
    """Goals with start stamps, a replacement and a cancel: the bag equals the offline loop.

    The offline loop is handed each goal before the sample its recorded events say it was
    taken at (and the cancel likewise): the nodes and the offline loop run the same execution.
    """
    from actuator_analysis.analyze import load_run
    from actuator_bringup.commanded import COMMANDED_DURATION_S, replay_offline, scripted_run
    from actuator_bringup.main import compare_with_offline

    duration = COMMANDED_DURATION_S
    result, client = scripted_run(isolated / 'bags', isolated / 'runs', duration_s=duration)
    assert all(code == 0 for code in result.exit_codes.values()), result.exit_codes
    assert not client.error and len(client.ids) == 3, (client.error, client.ids)
    run = load_run(result.bag, quiet=True)
    offline = replay_offline(run, client, duration_s=duration)
    comparison = compare_with_offline(run, offline.trace)
    assert comparison['samples_compared'] == round(duration * 1000)
    assert comparison['identical'], comparison
    kinds = [e.kind for e in offline.goal_events]
    assert kinds.count('started') == 3 and 'canceled' in kinds
    assert np.any(offline.trace['reference_velocity_rad_s'] != 0.0)
