# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A commanded run: the loop holding still, and a scripted client that moves it as ROS users do.

The loop runs the hold scenario (hold_pp_nftsmc_eso: Case 2's tuning, deep sea) as separate
processes with the recorder; a client thread of this process, with an rclpy context of its
own, sends the ``SCRIPT``: a multi-point goal, a second goal that replaces it mid-motion, and a
third that it cancels while the joint moves. Goals carry start stamps ahead of the loop's clock,
so each starts at a defined sample; the cancel takes effect at the sample it is handed over at,
which the controller's goal events record. ``replay_offline`` runs the offline loop with the
same goals handed over at the samples the events say: in sim time it equals the bag bit for
bit (tests/test_trajectory_nodes.py).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

from actuator_analysis.goals import GoalEventRow
from actuator_bringup.runner import RunResult, run_closed_loop
from actuator_controller.goal_execution import PREEMPTED, Goal
from actuator_controller.goal_rules import RequestPoint, TrajectoryRequest, waypoints
from actuator_sim.loop import ClosedLoop
from actuator_sim.params_yaml import all_scenarios
from actuator_sim.scenarios import HOLD_SCENARIO

JOINTS = ('joint',)
#: Sample time the commanded run lasts [s]: the script runs from when the client found the
#: action server (from_ready) and cancels its last goal 2.3 s later; the client may take up to
#: READY_BY_S of the loop's time to find it (a sim loop runs several times faster than real time).
COMMANDED_DURATION_S = 6.0
#: Loop time by which a client timing its script from_ready must have found the server [s].
READY_BY_S = COMMANDED_DURATION_S - 3.0


@dataclass(frozen=True)
class ScriptedGoal:
    """One goal of a script: its points (one joint) and when it is sent, starts, is cancelled."""

    name: str
    times_s: tuple
    positions_rad: tuple
    send_s: float  #: sent once the loop's clock has passed this [s]
    start_s: float  #: its header.stamp [s on the loop's clock]
    cancel_s: Optional[float] = None  #: cancelled once the loop's clock passes this [s]
    velocities_rad_s: Optional[tuple] = None  #: None: positions only
    accelerations_rad_s2: Optional[tuple] = None

    def request(self, stamp_ns: int = 0) -> TrajectoryRequest:
        """Return the trajectory as the controller takes it from the message (ns times)."""
        n = len(self.times_s)
        velocities = self.velocities_rad_s or (None,) * n
        accelerations = self.accelerations_rad_s2 or (None,) * n
        return TrajectoryRequest(
            JOINTS,
            tuple(
                RequestPoint(
                    int(round(t * 1e9)),
                    (p,),
                    () if v is None else (v,),
                    () if a is None else (a,),
                )
                for t, p, v, a in zip(self.times_s, self.positions_rad, velocities, accelerations)
            ),
            stamp_ns,
        )

    def message(self, stamp_ns: int):
        """Return the trajectory_msgs/JointTrajectory a client sends."""
        from actuator_controller.goal_client import joint_trajectory

        def column(values):
            return None if values is None else [[v] for v in values]

        return joint_trajectory(
            JOINTS,
            self.times_s,
            column(self.positions_rad),
            column(self.velocities_rad_s),
            column(self.accelerations_rad_s2),
            stamp_ns=stamp_ns,
        )


#: Multi-point, replaced mid-motion (sent just after the first starts moving, starting 0.45 s
#: later), and a third cancelled while it moves. Each is sent 0.3 s or more of loop time before
#: its start stamp: a client thread that lags a sim loop running several times faster than real
#: time on a loaded machine still hands each over before it starts. Times on the loop's clock
#: from when the client found the action server (ScriptedClient.t0_ns; in sim without from_ready:
#: from the joint's first sample, SIM_START_NS).
SCRIPT = (
    ScriptedGoal('multi-point', (0.3, 0.6, 0.9), (0.3, -0.2, 0.1), 0.05, 0.5),
    ScriptedGoal('replacement', (0.3, 0.6), (-0.3, 0.0), 0.6, 1.05),
    ScriptedGoal('cancelled', (0.8,), (0.5,), 1.7, 2.0, cancel_s=2.3),
)


def _reached(now_ns: Optional[int], at_ns: float) -> bool:
    """Whether the client's clock (None: no /clock yet) has reached ``at_ns``."""
    return now_ns is not None and now_ns >= at_ns


class ScriptedClient(threading.Thread):
    """Sends ``SCRIPT`` on the loop's clock (/clock in sim, the wall clock in real time)."""

    def __init__(
        self, mode: str, script=SCRIPT, timeout_s: float = 600.0, from_ready: bool = True
    ) -> None:
        """Run in ``mode``; give up after ``timeout_s`` of wall time.

        ``from_ready``: the script's times count from when the client found the action server
        (on the 1 ms grid in sim); False in sim: from the joint's first sample, however late
        the client is ready.
        """
        super().__init__(name='scripted-client', daemon=True)
        self.mode, self.script, self.timeout_s = mode, script, timeout_s
        self.from_ready = from_ready
        self.stop = threading.Event()
        self.ids: dict[str, str] = {}  # script name -> goal id
        self.runs: dict = {}
        self.t0_ns: Optional[int] = None
        self.error = ''

    def run(self) -> None:
        """Send, wait, cancel, until the script is done or the loop is gone."""
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rosgraph_msgs.msg import Clock

        from actuator_controller.goal_client import GoalClient
        from actuator_ros.joint_node import SIM_START_NS

        context = Context()
        rclpy.init(context=context)
        node = Node('scripted_client', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        clock: list[int] = []

        def on_clock(msg: Clock) -> None:
            clock.append(msg.clock.sec * 10**9 + msg.clock.nanosec)

        if self.mode == 'sim':
            node.create_subscription(Clock, '/clock', on_clock, 1)
        client = GoalClient(node)
        deadline = time.monotonic() + self.timeout_s

        def now_ns() -> Optional[int]:
            return (clock[-1] if clock else None) if self.mode == 'sim' else time.time_ns()

        def spin_until(predicate) -> bool:
            while not predicate():
                if self.stop.is_set() or time.monotonic() > deadline:
                    return False
                executor.spin_once(timeout_sec=0.005)
            return True

        try:
            if not spin_until(lambda: client.action.server_is_ready() and now_ns() is not None):
                self.error = 'no action server or clock'
                return
            ready_ns = now_ns()
            assert ready_ns is not None  # the clock ticked (spin_until above)
            self._set_t0(ready_ns, SIM_START_NS)
            if not self._send_script(client, spin_until, now_ns):
                return
            spin_until(lambda: all(r.done for r in self.runs.values()))
        finally:
            node.destroy_node()
            context.try_shutdown()

    def _set_t0(self, ready_ns: int, sim_start_ns: int) -> None:
        """Set the script's time origin from when the client found the server (``t0_ns``)."""
        if self.mode == 'sim':
            grid = 1_000_000  # the sim clock's sample grid: a start stamp on a sample
            ready_ns = sim_start_ns + -(-(ready_ns - sim_start_ns) // grid) * grid
            self.t0_ns = ready_ns if self.from_ready else sim_start_ns
            if self.from_ready and ready_ns - sim_start_ns > READY_BY_S * 1e9:
                self.error = (
                    f'the client found the action server only {ready_ns - sim_start_ns} ns '
                    f'into the run (by {READY_BY_S:g} s the script fits the run)'
                )
        else:
            self.t0_ns = ready_ns

    def _send_script(
        self,
        client,
        spin_until: Callable[[Callable[..., bool]], bool],
        now_ns: Callable[[], Optional[int]],
    ) -> bool:
        """Send each goal, cancel it when due; return False when a wait was cut short."""
        from actuator_controller.goal_client import follow_goal, goal_id

        t0_ns = self.t0_ns
        assert t0_ns is not None  # _set_t0 ran
        for goal in self.script:
            if not spin_until(lambda g=goal: _reached(now_ns(), t0_ns + g.send_s * 1e9)):
                return False
            stamp = t0_ns + int(round(goal.start_s * 1e9))
            run = client.send(follow_goal(goal.message(stamp)))
            self.runs[goal.name] = run
            if not spin_until(lambda r=run: r.accepted is not None):
                return False
            if run.accepted:
                self.ids[goal.name] = goal_id(run)
            if goal.cancel_s is not None and run.accepted:
                if not spin_until(lambda g=goal: _reached(now_ns(), t0_ns + g.cancel_s * 1e9)):
                    return False
                client.cancel(run)
        return True


def scripted_run(
    bag_root: Path,
    results_root: Path,
    mode: str = 'sim',
    duration_s: float = 3.0,
    script=SCRIPT,
    thread_priority: Optional[int] = None,
    from_ready: bool = True,
) -> tuple[RunResult, ScriptedClient]:
    """Run the hold scenario with the scripted client; return the run and the client.

    ``thread_priority``: the real-time runs' SCHED_FIFO priority (default 50 in real time, as
    the main job's paper case; 0 in sim). ``from_ready``: as ScriptedClient's.
    """
    if thread_priority is None:
        thread_priority = 50 if mode == 'realtime' else 0
    client = ScriptedClient(mode, script, from_ready=from_ready)
    client.start()
    try:
        result = run_closed_loop(
            HOLD_SCENARIO,
            mode,
            duration_s,
            bag_root=bag_root,
            results_root=results_root,
            quiet=True,
            thread_priority=thread_priority,
        )
    finally:
        client.stop.set()
        client.join(timeout=10.0)
    return result, client


@dataclass
class OfflineReplay:
    """The offline loop's trace and goal events for a recorded commanded run."""

    trace: dict
    goal_events: list


def handovers(events: list[GoalEventRow], ids: list[str]) -> list[int]:
    """Return the sample each goal (in the order sent) was handed over at, from its events.

    A goal that preempted the one before was handed over at that one's preemption; any other
    goal that started at the sample it started (one taken after its start stamp, or without
    one, starts when taken; one that waited for its stamp gives the same run handed over at any
    sample from its acceptance to its start); one that never started no earlier than it was
    accepted and the one before had ended.
    """
    out = []
    for i, goal_id in enumerate(ids):
        mine = [e for e in events if e.goal_id == goal_id]
        kinds = {e.kind: e for e in mine}
        previous = [e for e in events if i and e.goal_id == ids[i - 1]]
        preempted = [e for e in previous if e.kind == 'aborted' and e.error_string == PREEMPTED]
        if preempted:
            out.append(preempted[0].stamp_ns)
        elif 'started' in kinds:
            out.append(kinds['started'].stamp_ns)
        else:
            ended = [
                e.stamp_ns for e in previous if e.kind in ('succeeded', 'aborted', 'canceled')
            ]
            out.append(max([kinds['accepted'].stamp_ns, *ended]))
    return out


def replay_offline(run, client: ScriptedClient, duration_s: float) -> OfflineReplay:
    """Run the offline loop of the hold scenario with the client's goals, as the bag says."""
    scenario = all_scenarios()[HOLD_SCENARIO]
    scenario.duration_s = duration_s
    loop = ClosedLoop(scenario)
    tolerances = scenario.trajectory.default_tolerances()
    sent = [g for g in client.script if g.name in client.ids]
    ids = [client.ids[g.name] for g in sent]
    t0 = run.t0_ns  # the bag's first sample is the offline loop's sample 0
    assert client.t0_ns is not None  # the client ran
    for goal, goal_id, at_ns in zip(sent, ids, handovers(run.goal_events, ids)):
        stamp = client.t0_ns + int(round(goal.start_s * 1e9)) - t0
        points = waypoints(goal.request(), JOINTS)
        loop.submit_at(at_ns - t0, Goal(goal_id, points, tolerances, stamp))
        canceled = [e for e in run.goal_events if e.goal_id == goal_id and e.kind == 'canceled']
        if canceled:
            loop.cancel_at(canceled[0].stamp_ns - t0, goal_id)
    trace = loop.run()
    return OfflineReplay(trace, loop.goal_events)
