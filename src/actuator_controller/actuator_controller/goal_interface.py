# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The controller's trajectory interface, JTC's names: an action and a topic, off the 1 kHz path.

    <controller>/follow_joint_trajectory  control_msgs/action/FollowJointTrajectory
    <controller>/joint_trajectory         trajectory_msgs/JointTrajectory (fire-and-forget)
    controller/goal_events                actuator_msgs/GoalEvent (what became of each)

Both live on a node of their own (``<controller>_goals``, same namespace) spun by a thread of
its own, so the control executor waits on exactly what it waited on before (no action server
entities in its wait set; ``actuator_bench.action_executor_probe`` measured the alternatives).
The goal thread checks a goal (JTC's rules, the tolerances, whether the joint can follow it
from the desired state now: goal_rules) and posts it to a ``Mailbox``; the control thread
takes it after its next sample and hands ``TrajectoryExecution`` events back through a deque,
which this thread turns into feedback, results and GoalEvents at ``action_monitor_rate`` (as
JTC's action monitor).
A refused goal is rejected (as JTC) and the reason logged in one line and published.
"""

from __future__ import annotations

import collections
import itertools
import threading
import traceback
from typing import Optional

import rclpy
from control_msgs.action import FollowJointTrajectory
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from actuator_controller.goal_execution import (
    ABORTED,
    CANCELED,
    STARTED,
    SUCCEEDED,
    Goal,
    GoalEvent,
    Mailbox,
    TrajectoryExecution,
)
from actuator_controller.goal_rules import (
    NOT_RUNNING,
    RequestPoint,
    TrajectoryRequest,
    feasibility_refusal,
    resolve_tolerances,
    trajectory_refusal,
    unchecked_note,
    waypoints,
)
from actuator_controller.trajectory import DesiredState, Waypoints, plan
from actuator_core.timing import stamp_to_ns
from actuator_msgs.msg import GoalEvent as GoalEventMsg

#: GoalEvent.event of each execution event kind.
EVENT_CODES = {
    STARTED: GoalEventMsg.EVENT_STARTED,
    SUCCEEDED: GoalEventMsg.EVENT_SUCCEEDED,
    ABORTED: GoalEventMsg.EVENT_ABORTED,
    CANCELED: GoalEventMsg.EVENT_CANCELED,
}
#: A goal naming multi-DOF joints is refused, not ignored (JTC ignores it): the loop has none.
MULTI_DOF_REFUSED = (
    'multi_dof_trajectory and component tolerances are not supported: the loop has no '
    'multi-DOF joint'
)
#: How long the goal thread waits in its executor per turn [s] (its stop is seen this late).
SPIN_S = 0.05


def trajectory_request(msg: JointTrajectory) -> TrajectoryRequest:
    """Return the message as ROS-free data (goal_rules)."""
    return TrajectoryRequest(
        tuple(msg.joint_names),
        tuple(
            RequestPoint(
                stamp_to_ns(p.time_from_start),
                tuple(p.positions),
                tuple(p.velocities),
                tuple(p.accelerations),
                tuple(p.effort),
            )
            for p in msg.points
        ),
        stamp_to_ns(msg.header.stamp),
    )


def _point(positions, velocities=None, accelerations=None) -> JointTrajectoryPoint:
    point = JointTrajectoryPoint()
    point.positions = [float(p) for p in positions]
    if velocities is not None:
        point.velocities = [float(v) for v in velocities]
    if accelerations is not None:
        point.accelerations = [float(a) for a in accelerations]
    return point


def _ns_to_time(stamp_ns: int):
    from builtin_interfaces.msg import Time

    return Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)


class GoalInterface:
    """The action server and the topic on a node and thread of their own."""

    def __init__(self, controller, reference) -> None:
        """Create the node, the interfaces and the thread (the controller's configure).

        ``reference``: the assembly's; goals run on it when it is the commanded one (hold).
        """
        self.controller = controller
        self.params = controller.params
        common = self.params.common
        self.execution: Optional[TrajectoryExecution] = (
            TrajectoryExecution(
                reference,
                self.params.trajectory,
                (common.theta1n, common.theta2n, common.current_limit_a),
            )
            if self.params.kind == 'hold'
            else None
        )
        self.mailbox = Mailbox()
        self.refused_count = itertools.count(1)
        self.outbox: collections.deque = collections.deque()  # GoalEvents from the control thread
        self.joint_names = tuple(self.params.trajectory.joint_names)
        self.log = controller.get_logger()
        self.node = Node(
            f'{controller.get_name()}_goals',
            namespace=controller.get_namespace(),
            context=controller.context,
            use_global_arguments=False,  # a __node remap of the process must not rename it
            start_parameter_services=False,
        )
        prefix = controller.get_name()
        self.server = ActionServer(
            self.node,
            FollowJointTrajectory,
            f'{prefix}/follow_joint_trajectory',
            execute_callback=self._execute,
            goal_callback=self._on_goal,
            cancel_callback=self._on_cancel,
        )
        self.subscription = self.node.create_subscription(
            JointTrajectory, f'{prefix}/joint_trajectory', self._on_topic, 10
        )
        self.events_pub = self.node.create_publisher(
            GoalEventMsg,
            'controller/goal_events',
            QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE),
        )
        self.timer = self.node.create_timer(
            1.0 / self.params.trajectory.goal.action_monitor_rate,
            self._monitor,
            clock=RosClock(clock_type=ClockType.STEADY_TIME),
        )
        self.prepared: dict[int, tuple] = {}  # id(goal message) -> what _check made of it
        self.running: dict[str, tuple] = {}  # goal id -> (goal handle, result future)
        self.topic_count = itertools.count(1)
        self.executor = SingleThreadedExecutor(context=controller.context)
        self.executor.add_node(self.node)
        self.stopping = threading.Event()
        self.thread = threading.Thread(target=self._spin, name='goals', daemon=True)
        self.thread.start()

    # --- the goal thread -------------------------------------------------------------------------
    def _spin(self) -> None:
        """Run the goal node's callbacks until closed; a failing callback is logged, not fatal."""
        while not self.stopping.is_set() and rclpy.ok(context=self.controller.context):
            try:
                self.executor.spin_once(timeout_sec=SPIN_S)
            except Exception:  # noqa: BLE001 - the thread must outlive one bad callback
                self.log.error(f'goal thread: a callback failed:\n{traceback.format_exc()}')

    def close(self) -> None:
        """Send what is pending, stop the thread, destroy the interfaces (cleanup)."""
        self.stopping.set()
        self.thread.join(timeout=2.0)
        self._monitor()
        for handle, done in self.running.values():  # nothing left to end them: say so
            handle.abort()
            done.set_result(
                FollowJointTrajectory.Result(
                    error_code=FollowJointTrajectory.Result.INVALID_GOAL,
                    error_string='the controller was cleaned up',
                )
            )
        self.running.clear()
        for _ in range(5):  # let the execute coroutines return their results
            self.executor.spin_once(timeout_sec=0.01)
        self.server.destroy()
        self.executor.remove_node(self.node)
        self.node.destroy_node()
        self.executor.shutdown(timeout_sec=0.1)

    def _refuse(self, goal_id: str, from_action: bool, why: str) -> None:
        """Log and publish why a trajectory was not taken."""
        self.log.error(f'trajectory {goal_id} refused: {why}')
        newest = 0 if self.execution is None else self.execution.newest_stamp_ns
        self._publish(GoalEvent(newest, goal_id, 'refused', error_string=why), from_action)

    def _check(self, msg: JointTrajectory, tolerances_of=None) -> tuple:
        """(goal parts, refusal): JTC's rules, the tolerances, and the plan from now."""
        if self.params.kind != 'hold':
            return None, (
                f"the controller follows its built-in '{self.params.kind}' reference (parameter "
                "reference): it takes goals with reference 'hold'"
            )
        if not self.controller.active:
            return None, NOT_RUNNING
        execution = self.execution
        assert execution is not None  # a 'hold' reference has one
        blocked = execution.blocked
        if blocked:
            return None, f"Can't accept new trajectories: {blocked}"
        request = trajectory_request(msg)
        now_ns = execution.newest_stamp_ns
        goal = self.params.trajectory.goal
        refusal = trajectory_refusal(
            request, self.joint_names, goal.allow_nonzero_velocity_at_trajectory_end, now_ns
        )
        if refusal:
            return None, refusal
        defaults = self.params.trajectory.default_tolerances()
        tolerances, refusal = (
            tolerances_of(defaults) if tolerances_of is not None else (defaults, '')
        )
        if refusal:
            return None, refusal
        points = waypoints(request, self.joint_names)
        elapsed_s = max(0.0, (now_ns - request.stamp_ns) * 1e-9) if request.stamp_ns else 0.0
        ahead = points.after(elapsed_s)
        if len(ahead.times_s):
            desired = execution.desired or DesiredState(
                (0.0,) * len(self.joint_names),
                (0.0,) * len(self.joint_names),
                (0.0,) * len(self.joint_names),
            )
            shifted = Waypoints(
                ahead.times_s - elapsed_s, ahead.positions, ahead.velocities, ahead.accelerations
            )
            common = self.params.common
            refusal = feasibility_refusal(
                plan(0.0, desired, shifted),
                self.joint_names,
                goal,
                common.theta1n,
                common.theta2n,
                common.current_limit_a,
            )
            if refusal:
                return None, refusal
        return (points, tolerances, request), ''

    def _on_goal(self, goal) -> GoalResponse:
        """Accept or reject a goal of the action (JTC: a rejected goal gets no result)."""

        def tolerances_of(defaults):
            return resolve_tolerances(
                defaults,
                self.joint_names,
                [(t.name, t.position, t.velocity, t.acceleration) for t in goal.path_tolerance],
                [(t.name, t.position, t.velocity, t.acceleration) for t in goal.goal_tolerance],
                stamp_to_ns(goal.goal_time_tolerance) * 1e-9,
            )

        multi_dof = goal.multi_dof_trajectory
        if (
            multi_dof.points
            or multi_dof.joint_names
            or goal.component_path_tolerance
            or (goal.component_goal_tolerance)
        ):
            parts, why = None, MULTI_DOF_REFUSED
        else:
            parts, why = self._check(goal.trajectory, tolerances_of)
        if why:  # rclpy gives goal_callback no goal id: the refusal is numbered
            self._refuse(f'refused-{next(self.refused_count)}', True, why)
            return GoalResponse.REJECT
        assert parts is not None  # _check made them, or said why not
        self.prepared[id(goal)] = parts  # the same message object reaches _execute
        return GoalResponse.ACCEPT

    async def _execute(self, goal_handle):
        """Post the goal to the control thread; return its result when the execution ends it."""
        goal_id = bytes(goal_handle.goal_id.uuid).hex()
        points, tolerances, request = self.prepared.pop(id(goal_handle.request))
        note = unchecked_note(tolerances, self.joint_names)
        if note:
            self.log.warning(f'goal {goal_id}: {note}')
        done = Future()
        self.running[goal_id] = (goal_handle, done)
        self._accepted(goal_id, True, request, points)
        self.mailbox.post(('goal', Goal(goal_id, points, tolerances, request.stamp_ns, True)))
        return await done

    def _on_cancel(self, goal_handle) -> CancelResponse:
        """Accept a cancel of a running goal; it ends when the control thread has stopped it."""
        goal_id = bytes(goal_handle.goal_id.uuid).hex()
        if goal_id not in self.running:
            return CancelResponse.REJECT
        self.mailbox.post(('cancel', goal_id))
        return CancelResponse.ACCEPT

    def _on_topic(self, msg: JointTrajectory) -> None:
        """Take a trajectory from the topic: checked as a goal, no result (fire-and-forget)."""
        goal_id = f'topic-{next(self.topic_count)}'
        parts, why = self._check(msg)
        if why:
            self._refuse(goal_id, False, why)
            return
        points, tolerances, request = parts
        self._accepted(goal_id, False, request, points)
        self.mailbox.post(('goal', Goal(goal_id, points, tolerances, request.stamp_ns, False)))

    def _accepted(self, goal_id: str, from_action: bool, request, points) -> None:
        assert self.execution is not None  # _check accepted it: a 'hold' reference has one
        msg = self._event_msg(
            GoalEvent(self.execution.newest_stamp_ns, goal_id, 'accepted'), from_action
        )
        msg.start = _ns_to_time(request.stamp_ns)
        msg.points = len(request.points)
        msg.interpolation = points.kind
        self.events_pub.publish(msg)
        self.log.info(
            f'trajectory {goal_id} accepted: {len(request.points)} points '
            f'({points.kind}), last due {points.times_s[-1]:g} s after '
            + ('the sample it is taken at' if not request.stamp_ns else f'{request.stamp_ns} ns')
        )

    def _event_msg(self, event: GoalEvent, from_action: bool) -> GoalEventMsg:
        msg = GoalEventMsg()
        msg.header.stamp = _ns_to_time(event.stamp_ns)
        msg.goal_id = event.goal_id
        msg.from_action = from_action
        msg.event = {
            'refused': GoalEventMsg.EVENT_REFUSED,
            'accepted': GoalEventMsg.EVENT_ACCEPTED,
        }.get(event.kind, EVENT_CODES.get(event.kind, GoalEventMsg.EVENT_ABORTED))
        msg.error_code = event.error_code
        msg.error_string = event.error_string
        msg.end = _ns_to_time(event.end_ns)
        return msg

    def _publish(self, event: GoalEvent, from_action: bool) -> None:
        self.events_pub.publish(self._event_msg(event, from_action))

    def _monitor(self) -> None:
        """Feedback of the running goal; results and GoalEvents of what the control thread did."""
        while self.outbox:
            event = self.outbox.popleft()
            entry = self.running.get(event.goal_id)
            self._publish(event, entry is not None or not event.goal_id.startswith('topic-'))
            if event.kind == STARTED:
                continue
            text = f'trajectory {event.goal_id} {event.kind}: {event.error_string}'.rstrip(': ')
            if event.kind in (SUCCEEDED, CANCELED):  # one call site per severity (rclpy)
                self.log.info(text)
            else:
                self.log.warning(text)
            if entry is None:
                continue
            handle, done = self.running.pop(event.goal_id)
            result = FollowJointTrajectory.Result()
            result.error_code = event.error_code
            result.error_string = event.error_string
            if event.kind == SUCCEEDED:
                handle.succeed()
            elif event.kind == CANCELED:
                handle.canceled()
            else:
                handle.abort()
            done.set_result(result)
        self._feedback()

    def _feedback(self) -> None:
        feedback = None if self.execution is None else self.execution.feedback
        if feedback is None or feedback.goal_id not in self.running:
            return
        handle, _ = self.running[feedback.goal_id]
        msg = FollowJointTrajectory.Feedback()
        msg.header.stamp = _ns_to_time(feedback.stamp_ns)
        msg.joint_names = list(self.joint_names)
        desired = feedback.desired
        msg.desired = _point(desired.positions, desired.velocities, desired.accelerations)
        msg.actual = _point(feedback.actual_positions, feedback.actual_velocities)
        msg.error = _point(
            [d - a for d, a in zip(desired.positions, feedback.actual_positions)],
            None
            if feedback.actual_velocities is None
            else [d - a for d, a in zip(desired.velocities, feedback.actual_velocities)],
        )
        handle.publish_feedback(msg)

    # --- the control thread ----------------------------------------------------------------------
    def after_sample(self, sample) -> None:
        """Hand the execution what the goal thread posted, and this sample (after it went out)."""
        execution = self.execution
        if execution is None:
            return
        if self.mailbox.waiting:
            for kind, item in self.mailbox.take():
                if kind == 'goal':
                    execution.submit(item)
                else:
                    execution.cancel(item)
        ref = sample.reference
        desired = (
            None
            if ref is None
            else DesiredState(
                (ref.position_rad,), (ref.velocity_rad_s,), (ref.acceleration_rad_s2,)
            )
        )
        estimate = sample.estimate
        velocities = None if estimate is None or self.params.name == 'pi' else (estimate[0],)
        execution.after_sample(
            sample.stamp_ns, sample.status, sample.t_s, desired, (sample.y,), velocities
        )
        if execution.events:
            self.outbox.extend(execution.take_events())  # deque appends are thread-safe

    def deactivate(self, stamp_ns: int) -> None:
        """Abort goals posted, waiting or running: the node deactivates (JTC's string)."""
        execution = self.execution
        if execution is None:
            return
        for kind, item in self.mailbox.take():
            if kind == 'goal':
                execution.submit(item)
        execution.deactivate(stamp_ns)
        self.outbox.extend(execution.take_events())
