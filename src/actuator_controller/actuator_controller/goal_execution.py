# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Goals in, events out, once per sample: joint_trajectory_controller's execution, ROS-free.

``TrajectoryExecution`` is called after every sample the controller publishes (``after_sample``)
by the controller node's control thread and by the offline loop alike, so a commanded run
simulates offline exactly as the nodes run it. Commands (a goal, a cancel, a stop) queue and
take effect after the next sample; each result is a ``GoalEvent`` stamped with the sample it
took effect at. Rules, as JTC's unless said:

* one goal at a time: a new one preempts the running or waiting one (ABORTED, INVALID_GOAL,
  JTC's string); a goal whose ``start_ns`` (header.stamp) is ahead waits for the first sample
  stamped at or after it, while the previous motion goes on; its plan then starts from the
  desired state the law used at that sample, its points due at start_ns + time_from_start;
* until the last point is due, the path tolerances hold (PATH_TOLERANCE_VIOLATED); after it, the
  goal succeeds at the first sample within the goal tolerances, or aborts once goal_time has
  passed (GOAL_TOLERANCE_VIOLATED). An abort stops the joint's own state (its angle, the
  observer's velocity) within the deceleration bound and holds; a cancel stops the desired
  state the same way (it does not step to a hold, as JTC's default does);
* while the controller resynchronises, has latched its safe stop or sees two publishers, the
  law does not run and the joint is braked: a running or waiting goal aborts (INVALID_GOAL,
  saying why), and ``blocked`` tells the goal thread to refuse new ones. After a resync the
  assembly restarts the reference from the joint's angle (a hold).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import NamedTuple, Optional

from actuator_controller.commanded_reference import CommandedReference
from actuator_controller.goal_rules import feasibility_refusal, tolerance_violation
from actuator_controller.trajectory import DesiredState, Waypoints, plan
from actuator_controller.trajectory_settings import SegmentTolerances, TrajectorySettings
from actuator_core.status import Status

# control_msgs/action/FollowJointTrajectory result codes.
SUCCESSFUL = 0
INVALID_GOAL = -1
OLD_HEADER_TIMESTAMP = -3
PATH_TOLERANCE_VIOLATED = -4
GOAL_TOLERANCE_VIOLATED = -5

#: How a goal ended, and the sample it started at (GoalEvent.kind).
STARTED, SUCCEEDED, ABORTED, CANCELED = 'started', 'succeeded', 'aborted', 'canceled'
#: JTC's strings.
GOAL_REACHED = 'Goal successfully reached!'
PATH_VIOLATED = 'Aborted due to path tolerance violation'
PREEMPTED = 'Current goal preempted by new incoming action.'
DEACTIVATED = 'Current goal cancelled during deactivate transition.'
PREEMPTED_BY_TOPIC = 'Current goal preempted by a trajectory on the joint_trajectory topic.'
#: Why goals are refused (and running ones abort) while the law does not run, by status.
BLOCKING = {
    Status.RESYNC: 'the controller is resynchronising (0 A and brake while the observer '
    "converges, then it holds the joint's angle)",
    Status.LATCHED: 'the controller latched its safe stop (clean up and configure it again)',
    Status.CONFLICT: 'more than one publisher feeds a control input (0 A until one is left)',
}
#: Segments at a goal's start whose plan depends on the start state (the first, and for
#: positions-only points the second: its first knot's derivatives use the start's angle).
HEAD_SEGMENTS = 2


class GoalEvent(NamedTuple):
    """What happened to a goal, at which sample (actuator_msgs/GoalEvent)."""

    stamp_ns: int
    goal_id: str
    kind: str
    error_code: int = SUCCESSFUL
    error_string: str = ''
    end_ns: int = 0  #: STARTED: when its last point is due [ns]


@dataclass(frozen=True)
class Goal:
    """A trajectory taken: from the action (monitored) or the topic (fire-and-forget)."""

    goal_id: str
    waypoints: Waypoints  #: times from ``start_ns``
    tolerances: SegmentTolerances
    start_ns: int = 0  #: header.stamp; 0: at the sample it is taken
    from_action: bool = True


class Feedback(NamedTuple):
    """The running goal at one sample: desired, actual, error (desired - actual, as JTC)."""

    stamp_ns: int
    goal_id: str
    desired: DesiredState
    actual_positions: tuple
    actual_velocities: Optional[tuple]


class Mailbox:
    """Commands from the goal thread to the control thread: post there, take here.

    ``waiting`` is read without the lock on every sample (an attribute read); the lock is taken
    only when something waits.
    """

    def __init__(self) -> None:
        """Empty."""
        self._lock = threading.Lock()
        self._items: list = []
        self.waiting = False

    def post(self, item) -> None:
        """Queue one command (any thread)."""
        with self._lock:
            self._items.append(item)
            self.waiting = True

    def take(self) -> list:
        """Every queued command, oldest first (the control thread)."""
        with self._lock:
            items, self._items = self._items, []
            self.waiting = False
        return items


class TrajectoryExecution:
    """Runs goals on a CommandedReference and judges them sample by sample."""

    def __init__(
        self,
        reference: CommandedReference,
        settings: TrajectorySettings,
        dynamics: tuple,
    ) -> None:
        """``dynamics``: (theta1n, theta2n, current_limit_a) for the start-up check."""
        self.reference = reference
        self.settings = settings
        self.joint_names = tuple(settings.joint_names)
        self.dynamics = dynamics
        self.commands: list = []
        self.pending: Optional[Goal] = None
        self.active: Optional[Goal] = None
        self.active_end_ns = 0
        self.events: list[GoalEvent] = []
        # Snapshots for the goal thread (attribute writes: atomic under the GIL).
        self.blocked = ''
        self.newest_stamp_ns = 0
        self.desired: Optional[DesiredState] = None
        self.feedback: Optional[Feedback] = None
        self._t = 0.0  # the newest law sample's reference time [s]

    # --- commands (queued; take effect after the next sample) ------------------------------------
    def submit(self, goal: Goal) -> None:
        """Take ``goal``: it preempts the running or waiting one."""
        self.commands.append(('goal', goal))

    def cancel(self, goal_id: str) -> None:
        """Cancel ``goal_id`` (running: its desired motion stops; waiting: dropped)."""
        self.commands.append(('cancel', goal_id))

    def deactivate(self, stamp_ns: int) -> None:
        """Abort every goal now (the node deactivates; JTC's string); the motion stops."""
        for kind, item in self._take_commands():
            if kind == 'goal':
                self._end(stamp_ns, item, ABORTED, INVALID_GOAL, DEACTIVATED)
        for goal in (self.pending, self.active):
            if goal is not None:
                self._end(stamp_ns, goal, ABORTED, INVALID_GOAL, DEACTIVATED)
        self.pending = self.active = self.feedback = None
        if self.desired is not None and self.reference.moving:
            self.reference.stop(self._t, self.desired)

    def take_events(self) -> list[GoalEvent]:
        """Return the events since the last call (oldest first)."""
        events, self.events = self.events, []
        return events

    # --- once per published sample ---------------------------------------------------------------
    def after_sample(
        self,
        stamp_ns: int,
        status: Status,
        t_s: Optional[float],
        desired: Optional[DesiredState],
        actual_positions: tuple,
        actual_velocities: Optional[tuple],
    ) -> None:
        """Judge the running goal on sample ``stamp_ns`` and apply the queued commands.

        ``t_s`` None: the law did not run for this sample (a safe sample); ``status`` says why.
        ``desired``: the reference the law used at t_s. ``actual_velocities`` None when the
        law has no velocity estimate (PI).
        """
        self.newest_stamp_ns = stamp_ns
        if t_s is None:
            self.blocked = BLOCKING.get(status, '')
            if self.blocked:
                self._abort_all(stamp_ns, f'Aborted: {self.blocked}')
                self._refuse_commands(stamp_ns, f'Aborted: {self.blocked}')
            return
        assert desired is not None  # the law ran: on this reference
        self.blocked = ''
        self._t = t_s
        self.desired = desired
        if not (self.active or self.pending or self.commands):
            return  # holding, nothing asked: the sample costs this much
        if self.active is not None:
            self._judge(stamp_ns, t_s, desired, actual_positions, actual_velocities)
        for command in self._take_commands():
            self._apply(stamp_ns, t_s, desired, command)
        if self.pending is not None and (
            self.pending.start_ns == 0 or self.pending.start_ns <= stamp_ns
        ):
            goal, self.pending = self.pending, None
            self._start(stamp_ns, t_s, desired, goal)
        if self.active is not None and self.active.from_action:
            self.feedback = Feedback(
                stamp_ns, self.active.goal_id, desired, actual_positions, actual_velocities
            )

    # --- internals -------------------------------------------------------------------------------
    def _take_commands(self) -> list:
        commands, self.commands = self.commands, []
        return commands

    def _refuse_commands(self, stamp_ns: int, why: str) -> None:
        """While the law does not run: queued goals end at once (cancels have nothing to do)."""
        for kind, item in self._take_commands():
            if kind == 'goal':
                self._end(stamp_ns, item, ABORTED, INVALID_GOAL, why)

    def _apply(self, stamp_ns: int, t_s: float, desired: DesiredState, command) -> None:
        kind, item = command
        if kind == 'goal':
            why = PREEMPTED if item.from_action else PREEMPTED_BY_TOPIC
            for old in (self.pending, self.active):
                if old is not None:
                    self._end(stamp_ns, old, ABORTED, INVALID_GOAL, why)
            self.active = self.feedback = None
            self.pending = item
        elif kind == 'cancel':
            if self.pending is not None and self.pending.goal_id == item:
                self._end(stamp_ns, self.pending, CANCELED)
                self.pending = None
            if self.active is not None and self.active.goal_id == item:
                self._end(stamp_ns, self.active, CANCELED)
                self.active = self.feedback = None
                self.reference.stop(t_s, desired)

    def _start(self, stamp_ns: int, t_s: float, desired: DesiredState, goal: Goal) -> None:
        """Plan ``goal`` from the desired state at this sample; check the start-dependent head."""
        elapsed_s = (stamp_ns - goal.start_ns) * 1e-9 if goal.start_ns else 0.0
        ahead = goal.waypoints.after(elapsed_s)
        if len(ahead.times_s) == 0:
            self._end(
                stamp_ns,
                goal,
                ABORTED,
                OLD_HEADER_TIMESTAMP,
                'Every point of the trajectory was due before the sample it started at',
            )
            return
        shifted = Waypoints(
            ahead.times_s - elapsed_s, ahead.positions, ahead.velocities, ahead.accelerations
        )
        segments = plan(t_s, desired, shifted)
        refusal = feasibility_refusal(
            segments.head(HEAD_SEGMENTS), self.joint_names, self.settings.goal, *self.dynamics
        )
        if refusal:
            self._end(stamp_ns, goal, ABORTED, INVALID_GOAL, refusal)
            return
        self.reference.follow(segments)
        self.active = goal
        # when the last point is due, in ns as the stamps (no rounding of seconds decides it)
        last_ns = int(round(float(goal.waypoints.times_s[-1]) * 1e9))
        self.active_end_ns = (goal.start_ns or stamp_ns) + last_ns
        self.events.append(GoalEvent(stamp_ns, goal.goal_id, STARTED, end_ns=self.active_end_ns))

    def _judge(self, stamp_ns, t_s, desired, actual_positions, actual_velocities) -> None:
        """JTC's update: path tolerances before the end, goal tolerances after it."""
        goal = self.active
        assert goal is not None  # a goal runs
        position_errors = [d - a for d, a in zip(desired.positions, actual_positions)]
        velocity_errors = (
            None
            if actual_velocities is None
            else [d - a for d, a in zip(desired.velocities, actual_velocities)]
        )
        tolerances = goal.tolerances
        if stamp_ns < self.active_end_ns:
            violation = tolerance_violation(
                self.joint_names, position_errors, velocity_errors, tolerances.path
            )
            if not violation:
                return
            code, why = PATH_TOLERANCE_VIOLATED, f'{PATH_VIOLATED}: {violation}'
        else:
            outside = tolerance_violation(
                self.joint_names, position_errors, velocity_errors, tolerances.goal
            )
            if not outside:
                self._end(stamp_ns, goal, SUCCEEDED, SUCCESSFUL, GOAL_REACHED)
                self.active = self.feedback = None
                return
            late_s = (stamp_ns - self.active_end_ns) * 1e-9
            if not 0.0 < tolerances.goal_time_s < late_s:
                return  # goal_time 0 waits for ever
            code = GOAL_TOLERANCE_VIOLATED
            why = f'Aborted due to goal_time_tolerance exceeding by {late_s:f} seconds: {outside}'
        self._abort_here(stamp_ns, t_s, actual_positions, actual_velocities, desired, code, why)

    def _abort_here(
        self, stamp_ns, t_s, actual_positions, actual_velocities, desired, code, why
    ) -> None:
        """Abort the running goal; the joint's own state comes to rest and holds."""
        assert self.active is not None  # a goal runs
        self._end(stamp_ns, self.active, ABORTED, code, why)
        self.active = self.feedback = None
        velocities = desired.velocities if actual_velocities is None else actual_velocities
        zero = tuple(0.0 for _ in actual_positions)
        self.reference.stop(t_s, DesiredState(tuple(actual_positions), tuple(velocities), zero))

    def _abort_all(self, stamp_ns: int, why: str) -> None:
        for goal in (self.pending, self.active):
            if goal is not None:
                self._end(stamp_ns, goal, ABORTED, INVALID_GOAL, why)
        self.pending = self.active = self.feedback = None

    def _end(self, stamp_ns: int, goal: Goal, kind: str, code: int = SUCCESSFUL, why='') -> None:
        self.events.append(GoalEvent(stamp_ns, goal.goal_id, kind, code, why))
