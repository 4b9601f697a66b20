# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A client of the controller's trajectory interface (the main job's, the benchmark's, the tests').

The messages any JTC client sends; nothing here is needed by a user.

    client = GoalClient(node)                          # on a node the caller spins
    run = client.send(follow_goal(joint_trajectory(['joint'], [1.0], [[0.5]])))
    ...spin until run.done...; run.status, run.result.error_code, run.feedback
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Sequence

from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration, Time
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance
from rclpy.action import ActionClient
from rclpy.action.client import ClientGoalHandle
from rclpy.qos import QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from actuator_msgs.msg import GoalEvent


def _duration(seconds: float) -> Duration:
    ns = int(round(seconds * 1e9))
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def joint_trajectory(
    joint_names: Sequence[str],
    times_s: Sequence[float],
    positions: Sequence[Sequence[float]],
    velocities: Optional[Sequence[Sequence[float]]] = None,
    accelerations: Optional[Sequence[Sequence[float]]] = None,
    stamp_ns: int = 0,
) -> JointTrajectory:
    """Return a trajectory_msgs/JointTrajectory: a row of values per point, a column per joint."""
    msg = JointTrajectory()
    msg.header.stamp = Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
    msg.joint_names = list(joint_names)
    for i, t in enumerate(times_s):
        point = JointTrajectoryPoint()
        point.time_from_start = _duration(float(t))
        point.positions = [float(p) for p in positions[i]]
        if velocities is not None:
            point.velocities = [float(v) for v in velocities[i]]
        if accelerations is not None:
            point.accelerations = [float(a) for a in accelerations[i]]
        msg.points.append(point)
    return msg


def follow_goal(
    trajectory: JointTrajectory,
    path_tolerance: Sequence[tuple] = (),
    goal_tolerance: Sequence[tuple] = (),
    goal_time_tolerance_s: float = 0.0,
) -> FollowJointTrajectory.Goal:
    """Return a FollowJointTrajectory goal; tolerances (name, position, velocity, acceleration)."""
    goal = FollowJointTrajectory.Goal()
    goal.trajectory = trajectory
    goal.path_tolerance = [
        JointTolerance(name=n, position=float(p), velocity=float(v), acceleration=float(a))
        for n, p, v, a in path_tolerance
    ]
    goal.goal_tolerance = [
        JointTolerance(name=n, position=float(p), velocity=float(v), acceleration=float(a))
        for n, p, v, a in goal_tolerance
    ]
    goal.goal_time_tolerance = _duration(goal_time_tolerance_s)
    return goal


@dataclass
class GoalRun:
    """One goal sent: its handle once answered, its feedback, its end."""

    goal: FollowJointTrajectory.Goal
    handle: Optional[ClientGoalHandle] = None  #: None until the server answered
    accepted: Optional[bool] = None  #: None until the server answered
    status: Optional[int] = None  #: action_msgs/GoalStatus at the end
    result: Optional[FollowJointTrajectory.Result] = None
    feedback: list = field(default_factory=list)

    @property
    def done(self) -> bool:
        """Rejected, or ended (succeeded, aborted, canceled)."""
        return self.accepted is False or self.status is not None

    @property
    def succeeded(self) -> bool:
        """Ended with SUCCEEDED."""
        return self.status == GoalStatus.STATUS_SUCCEEDED


class GoalClient:
    """The action, the topic and the goal events of one controller, on the caller's node."""

    def __init__(self, node, controller: str = 'actuator_controller') -> None:
        """Create the action client, the topic publisher and the goal-event subscription."""
        self.node = node
        self.action = ActionClient(
            node, FollowJointTrajectory, f'{controller}/follow_joint_trajectory'
        )
        self.topic = node.create_publisher(JointTrajectory, f'{controller}/joint_trajectory', 10)
        self.events: list = []
        node.create_subscription(
            GoalEvent,
            'controller/goal_events',
            self.events.append,
            QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE),
        )

    def send(self, goal: FollowJointTrajectory.Goal) -> GoalRun:
        """Send ``goal``; the returned run fills in as the caller spins the node."""
        run = GoalRun(goal)

        def answered(future) -> None:
            handle = run.handle = future.result()
            run.accepted = bool(handle.accepted)
            if run.accepted:
                handle.get_result_async().add_done_callback(ended)

        def ended(future) -> None:
            response = future.result()
            run.result = response.result
            run.status = response.status

        future = self.action.send_goal_async(
            goal, feedback_callback=lambda m: run.feedback.append(m.feedback)
        )
        future.add_done_callback(answered)
        return run

    def cancel(self, run: GoalRun):
        """Ask to cancel ``run`` (answered goals only); returns the cancel's future."""
        assert run.handle is not None, 'the goal is not answered yet'
        return run.handle.cancel_goal_async()

    def publish(self, trajectory: JointTrajectory) -> None:
        """Send a trajectory on the topic (fire-and-forget)."""
        self.topic.publish(trajectory)

    def events_of(self, goal_id: str) -> list:
        """Return the goal events received for ``goal_id`` (a UUID in hex, or topic-<n>)."""
        return [e for e in self.events if e.goal_id == goal_id]


def goal_id(run: GoalRun) -> str:
    """Return the hex UUID the controller names ``run``'s goal by (in its goal events)."""
    assert run.handle is not None, 'the goal is not answered yet'
    return bytes(run.handle.goal_id.uuid).hex()
