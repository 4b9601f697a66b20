# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Joint controller node (managed): PP-NFTSMC-ESO at the sensor's 1 kHz.

(Or PI, SMC-ESO, NFTSMC-ESO.)

subscribes joint_states (sensor_msgs/JointState), eso/estimate (actuator_msgs/StateEstimate)
publishes  current_command (actuator_msgs/CurrentCommand),
           controller/state (actuator_msgs/ControllerState)
goals      <node>/follow_joint_trajectory (control_msgs/action/FollowJointTrajectory),
           <node>/joint_trajectory (trajectory_msgs/JointTrajectory), controller/goal_events
           (actuator_msgs/GoalEvent): with reference 'hold', on a node and thread of their own
           (goal_interface), judged sample by sample by the same TrajectoryExecution as offline

The node holds the control law and its ``ControlSampleAssembly`` (actuator_core), the same
objects as the offline loop: sample k is controlled as soon as y(k) and x_hat(k) are both in
(clocked by the sensor, as ros2_control's update follows its read). The node checks what
comes in, publishes what the assembly decides, and measures the timing.

Safety (statuses: actuator_core/status.py): every field of every input is checked against the
physical ranges of actuator_core.limits, before its stamp; a measurement no joint can make is
refused (``MeasurementPlausibility``); stamps pass a ``StampCheck`` (a stamp from the future
is refused; an estimate counts only for a measurement seen or the next sample; a jump of the
sensor's time base, or an observer restart, starts the resync policy: 0 A with the brake while
the observer converges, then the reference restarts from the joint's angle). A watchdog timer
at half the staleness timeout answers a stale input in grades (the assembly's recovery
policy), on the monotonic clock; more than one publisher on an input (seen when it matches,
``GraphGuard``), or another one on current_command (polled), stops control (0 A) until one is
left, and control then restarts as after a resync.
A non-finite output or a following error beyond the limit latches 0 A until the node is
cleaned up and configured again. Not active: no command at all; deactivate sends one 0 A
safe-stop command so the drive brakes at once.
"""

from __future__ import annotations

import time
from typing import Callable

from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from sensor_msgs.msg import JointState

from actuator_controller.controller_parameters import declare_controller_parameters
from actuator_controller.controller_report import ControllerReport
from actuator_controller.controller_state import controller_state_fields
from actuator_controller.goal_interface import GoalInterface
from actuator_controller.laws import make_controller
from actuator_controller.reference import make_reference
from actuator_core import limits
from actuator_core.assembly import ESTIMATE_AHEAD_SAMPLES, ControlSample, ControlSampleAssembly
from actuator_core.binding import MeasurementPlausibility
from actuator_core.clock import Clock, StampClock
from actuator_core.decimation import Decimator
from actuator_core.sample_log import SampleLog
from actuator_core.status import Status
from actuator_core.timebase import StampCheck, Verdict
from actuator_core.timing import period_ns, stamp_to_ns
from actuator_core.values import estimate_problem, measurement_problem
from actuator_msgs.msg import ControllerState, CurrentCommand, StateEstimate
from actuator_ros.conversions import joint_position
from actuator_ros.diagnostics import NodeDiagnostics
from actuator_ros.guard import GraphGuard
from actuator_ros.lockstep_hold import create_held_publisher
from actuator_ros.node import ManagedNode
from actuator_ros.qos import control_qos
from actuator_ros.runner import run_node
from actuator_ros.wire_io import codec, subscribe_views

NODE_NAME = 'actuator_controller'
STEADY = ClockType.STEADY_TIME
#: Inputs (matched events), and the output: another publisher on current_command drives the
#: joint beside this node (polled: this node does not subscribe it).
INPUT_TOPICS = ('joint_states', 'eso/estimate')
OUTPUT_TOPICS = ('current_command',)
WATCHED_TOPICS = INPUT_TOPICS + OUTPUT_TOPICS


class ControllerNode(ControllerReport, ManagedNode):
    """Runs one of the four control laws on the sensor/estimate streams."""

    def __init__(self, settings=None) -> None:
        """Declare and check every parameter; nothing is built before configure."""
        super().__init__(NODE_NAME, **({'settings': settings} if settings else {}))

    def load_parameters(self) -> None:
        """Declare (or read again at configure) and check every parameter."""
        self.params = declare_controller_parameters(self)

    # --- lifecycle -------------------------------------------------------------------------------
    def build(self) -> None:
        """Law, reference, assembly, stamp checks, topics and the watchdog."""
        self.period_ns = period_ns(self.params.common.dt_s)
        law = make_controller(self.params.name, self.params.gains, self.params.common)
        settings = self.params.settings
        reference = make_reference(
            self.params.kind,
            settings.reference_amplitude_rad,
            settings.reference_frequency_rad_s,
            self.params.trajectory.max_deceleration,
            excitation=self.params.excitation,
        )
        self.assembly = ControlSampleAssembly(
            law,
            reference,
            self.period_ns,
            self.params.name != 'pi',
            settings.following_error_limit_rad,
        )
        tolerance = int(settings.future_stamp_tolerance_s * 1e9)
        self.measurement_check = StampCheck(self.period_ns, self.params.mode == 'sim', tolerance)
        self.estimate_check = StampCheck(
            self.period_ns, self.params.mode == 'sim', tolerance + self.period_ns
        )
        self.clock = Clock()
        self.stamp_clock = StampClock(self.clock)  # stamp time, which a wall-clock step leaves
        self.plausibility = MeasurementPlausibility()
        self.guard = GraphGuard(self, self.on_conflict)
        qos = control_qos(self.params.mode)
        # sim: commands are held until the joint's and the observer's readers matched (a lost
        # u(0) leaves the lockstep waiting for good at start-up)
        self.cmd_pub, self.cmd_hold = create_held_publisher(
            self,
            CurrentCommand,
            'current_command',
            qos,
            settings.lockstep_subscribers if self.params.mode == 'sim' else 0,
        )
        self.state_pub = self.create_lifecycle_publisher(ControllerState, 'controller/state', qos)
        self.subs = [
            subscribe_views(
                self, kind, topic, callback, qos, event_callbacks=self.guard.callbacks(topic)
            )
            for kind, topic, callback in (
                (JointState, 'joint_states', self.on_measurement),
                (StateEstimate, 'eso/estimate', self.on_estimate),
            )
        ]
        # Half the shortest timeout is enough to notice staleness in time; a 1 kHz watchdog would
        # add a Python callback to every sample for nothing.
        # Real time: timers on the steady clock, so a wall-clock step neither stalls nor races
        # them; sim: on /clock, which the lockstep advances.
        timer_clock = (
            self.get_clock() if self.params.mode == 'sim' else RosClock(clock_type=STEADY)
        )
        shortest_timeout_ns = min(settings.measurement_timeout_ns, settings.estimate_timeout_ns)
        self.watchdog = self.create_timer(
            shortest_timeout_ns * 0.5e-9, self.on_watchdog, clock=timer_clock
        )
        # The longest this node is silent by design: a timeout and one watchdog period.
        self.quiet_ns = shortest_timeout_ns * 3 // 2
        self.graph_timer = self.create_timer(
            0.1, lambda: self.guard.poll(OUTPUT_TOPICS), clock=timer_clock
        )
        self.tick_timer = (
            self.create_timer(self.params.common.dt_s, self.on_tick, clock=timer_clock)
            if self.params.trigger == 'timer'
            else None
        )
        self.newest: tuple | None = None  # timer trigger: (stamp, y) of the newest measurement
        self.conflict = ''
        self.status = Status.WAITING
        self.late = self.refused = self.stale_events = self.gap_resyncs = self.resyncs = 0
        self.refusals: dict[str, int] = {}  # by reason, for /diagnostics
        self.measurements_in = self.estimates_in = 0
        self.envelope_restarts = 0
        self.received_ns = 0
        self.received_mono_ns: int | None = None
        self.command_done_ns: int | None = None  # perf_counter of the newest command published
        self.encode_command = codec(CurrentCommand).encode
        self.encode_state = codec(ControllerState).encode
        self.state_decimator = Decimator(settings.state_rate_hz)
        self.timing = SampleLog(('received_wall_ns', 'stamp_ns', 'latency_ns', 'compute_ns'))
        self.diagnostics = NodeDiagnostics(self, self.health_monitor(), self.health)
        params = self.params
        self.get_logger().info(
            f'{params.name} on the {params.kind} reference, {params.mode} mode, current limit '
            f'{params.common.current_limit_a} A; controller/state '
            + (f'at {settings.state_rate_hz:g} Hz' if settings.state_rate_hz else 'every sample')
        )
        self.goals = GoalInterface(self, reference)

    def stop(self) -> None:
        """One safe-stop command so the drive brakes now; the timing summary."""
        stamp = self.measurement_check.last_ns
        if stamp is not None:  # the command only: controller/state keeps one entry per sample
            self._publish(self.assembly.safe_sample(stamp, Status.INACTIVE), None, state=False)
        self.goals.deactivate(stamp or 0)
        self.close_log()

    def drop(self) -> None:
        """Destroy topics and timers."""
        self.goals.close()
        self.diagnostics.destroy()
        for timer in (self.watchdog, self.graph_timer, self.tick_timer):
            if timer is not None:
                self.destroy_timer(timer)
        for sub in self.subs:
            self.destroy_subscription(sub)
        for pub in (self.cmd_pub, self.state_pub):
            self.destroy_lifecycle_publisher(pub)

    # --- inputs ----------------------------------------------------------------------------------
    def _refuse(self, key: str, stamp: int | None, why: Callable[[], str]) -> None:
        """Count and log a refused input; answer its sample with 0 A (no brake: one sample).

        An error, but for an estimate merely ahead of this node's newest measurement: that is
        this node lagging the observer (a warning), not an input that is wrong.
        """
        self.refused += 1
        self.refusals[key] = self.refusals.get(key, 0) + 1
        (self.log.warn if key == 'estimate_ahead' else self.log.error)(key, why)
        if stamp is not None:
            self._publish(
                self.assembly.safe_sample(stamp, Status.INVALID_INPUT, safe_stop=False), None
            )

    def _received(self) -> int | None:
        """Receipt time for ages: monotonic in real time; None in sim (the stamps are time)."""
        return self.clock.now_ns() if self.params.mode == 'realtime' else None

    def on_measurement(self, msg: JointState) -> None:
        """y(k): checked, then the assembly; control sample k as soon as x_hat(k) is in."""
        if not self.active:
            return
        self.received_mono_ns = self._received()
        self.received_ns = self.stamp_clock.now_ns()  # stamp time: latency, the future check
        self.measurements_in += 1
        stamp = stamp_to_ns(msg.header.stamp)
        y = joint_position(msg, self.params.settings.joint_name)
        problem = measurement_problem(y, self.params.settings.joint_name, msg.position)
        if problem or y is None:  # before its stamp is taken: a refused value moves nothing
            self._refuse('bad_measurement', None, lambda: problem)
            return
        if self.conflict:  # whose sample this is cannot be told: no stamp is taken
            self._publish(self.assembly.safe_sample(stamp, Status.CONFLICT), None)
            return
        implausible = self.plausibility.check(stamp, y)
        rebased = bool(implausible) and self.plausibility.refuse(stamp, y)
        if implausible and not rebased:
            self._refuse('implausible', None, lambda: implausible)
            return
        verdict = self.measurement_check.check(stamp, self.received_ns)
        if verdict is Verdict.JUMP:  # a new time base: stamp time follows it from here
            self.stamp_clock.adopt(stamp, self.clock.now_ns())
        if verdict in (Verdict.FUTURE, Verdict.INVALID):
            self._refuse(
                verdict.value,
                None,
                lambda: (
                    f'measurement stamped {stamp} ns refused: '
                    + ('beyond the sample clock' if verdict is Verdict.FUTURE else 'not a stamp')
                ),
            )
            return
        if verdict is Verdict.OLD:
            return
        if verdict is Verdict.JUMP or rebased:
            self.get_logger().warning(
                'joint_states '
                + ('time base jumped' if verdict is Verdict.JUMP else 'stepped and stayed')
                + f' at {stamp} ns (a restarted sensor?): 0 A and brake until the observer has '
                'converged, then the reference restarts here'
            )
            self.plausibility.rebase(stamp, y)
            self.assembly.resync(stamp)
        else:
            self.plausibility.accept(stamp, y)
        if self.tick_timer is not None:  # timer trigger: the tick takes the newest measurement
            self.newest = (stamp, y)
            return
        self._take_measurement(stamp, y)

    def on_tick(self) -> None:
        """Timer trigger: control with the newest measurement not controlled yet."""
        if not self.active or self.newest is None:
            return
        stamp, y = self.newest
        self.newest = None
        self._take_measurement(stamp, y)

    def _take_measurement(self, stamp: int, y: float) -> None:
        """Hand y(k) to the assembly; log a resync it started."""
        started = time.perf_counter_ns()
        self._after_silence(started)
        self._control(self.assembly.add_measurement(stamp, y, self.received_mono_ns), started)

    def _after_silence(self, now_ns: int) -> None:
        """Real time: tell the assembly how long this node sent no command (a stall of its own)."""
        if self.params.mode == 'realtime' and self.command_done_ns is not None:
            self.assembly.command_gap(now_ns - self.command_done_ns, self.quiet_ns, now_ns)

    def on_estimate(self, msg: StateEstimate) -> None:
        """x_hat(k): every field checked against its physical range, then the assembly."""
        if not self.active:
            return
        self.estimates_in += 1
        stamp = stamp_to_ns(msg.header.stamp)
        x2, x3, u, gain = (
            msg.velocity_rad_s,
            msg.disturbance_rad_s2,
            msg.input_current_a,
            msg.input_current_gain,
        )
        field, problem = estimate_problem(
            x2, x3, u, gain, self.params.common.current_limit_a, self.params.common.dt_s
        )
        if problem:  # rate-limited per field, so each kind of refusal is reported
            self._refuse(
                f'bad_estimate {field}',
                None,
                lambda: f'estimate for {stamp} ns refused: {problem}',
            )
            return
        newest = self.assembly.newest_measurement_ns
        limit = None if newest is None else newest + ESTIMATE_AHEAD_SAMPLES * self.period_ns
        if msg.initial and limit is not None and limit < stamp <= limits.STAMP_MAX_NS:
            # A restarted observer (a new time base) may be ahead of this node's measurements:
            # the assembly keeps it aside, unused unless that measurement comes; no stamp taken.
            self.assembly.add_estimate(
                stamp, x2, x3, stamp_to_ns(msg.input_stamp), u, gain, True, self._received()
            )
            self.log.warn('initial_ahead', lambda: self.assembly.refusal)
            return
        now = self.stamp_clock.now_ns()
        verdict = self.estimate_check.check(stamp, now, limit)
        if verdict in (Verdict.FUTURE, Verdict.INVALID):
            # Two kinds, each reported: beyond this node's clock (no genuine estimate is), or
            # only ahead of its newest measurement (also this node lagging the observer's input:
            # dropped, since a law run on samples it sees late would chase at the limit).
            if verdict is Verdict.INVALID:
                kind = 'invalid_estimate'
            elif (
                self.params.mode == 'sim' or stamp > now + self.estimate_check.future_tolerance_ns
            ):
                kind = 'future_estimate'
            else:
                kind = 'estimate_ahead'
            self._refuse(
                kind,
                None,
                lambda: (
                    self.assembly.estimate_refusal(stamp)
                    or f'estimate stamped {stamp} ns refused: '
                    + ('beyond the sample clock' if verdict is Verdict.FUTURE else 'not a stamp')
                ),
            )
            return
        if verdict is Verdict.OLD and not msg.initial:
            return
        started = time.perf_counter_ns()
        self._after_silence(started)
        sample = self.assembly.add_estimate(
            stamp, x2, x3, stamp_to_ns(msg.input_stamp), u, gain, msg.initial, self._received()
        )
        why = self.assembly.refusal
        if why:
            self._refuse('estimate_binding', None, lambda: why)
        self._control(sample, started)

    def on_conflict(self, conflict: str) -> None:
        """Handle a change of the matched publishers: more than one stops control (then resync)."""
        if conflict != self.conflict:
            if conflict:
                self.get_logger().error(f'{conflict}: commanding 0 A until one publisher is left')
            else:
                self.get_logger().warning(
                    'one publisher per topic again: 0 A while the observer converges, then '
                    "the reference restarts from the joint's angle"
                )
                if self.measurement_check.last_ns is not None:
                    self.assembly.resync(self.measurement_check.last_ns)
            self.conflict = conflict

    def on_watchdog(self) -> None:
        """Stale measurement or estimate: command 0 A and say so (rate-limited)."""
        if not self.active:
            return
        now = (
            self.clock.now_ns()
            if self.params.mode == 'realtime'
            else self.get_clock().now().nanoseconds
        )
        if self.assembly.newest_measurement_ns is not None:  # a stall of this node may end here
            self._after_silence(time.perf_counter_ns())
        sample = self.assembly.watchdog(
            now,
            self.params.settings.measurement_timeout_ns,
            self.params.settings.estimate_timeout_ns,
        )
        if sample is None:
            return
        status = sample.status
        if self.status != status:
            self.stale_events += 1
        self.log.warn(
            'stale',
            lambda: (
                f'{status.name.lower().replace("_", " ")}: '
                + (
                    (
                        'commanding 0 A'
                        + (' with the brake' if sample.safe_stop else ' (no brake yet)')
                    )
                    if sample.command
                    else 'the joint holds the last command until its timeout'
                )
            ),
        )
        self._publish(sample, None)

    # --- output ----------------------------------------------------------------------------------
    def _control(self, sample: ControlSample | None, started_ns: int) -> None:
        """Publish a control update the assembly produced.

        Log the latch, restarts, late samples.
        """
        if sample is None:
            return
        self._log_recovery(sample)
        law = self.assembly.law
        if getattr(law, 'envelope_restarts', 0) != self.envelope_restarts:
            self.envelope_restarts = law.envelope_restarts
            self.log.warn(
                'envelope',
                lambda: (
                    f'error {float(sample.output.error_rad):.3g} rad left the prescribed '
                    f'envelope: restarted it (restart {self.envelope_restarts})'
                ),
            )
        if sample.status is Status.LATCHED and self.status is not Status.LATCHED:
            self.get_logger().error(
                'control output not finite or |error| beyond following_error_limit_rad '
                f'{self.params.settings.following_error_limit_rad}: safe stop latched (0 A) until '
                'cleanup'
            )
        self._publish(sample, started_ns)
        if sample.output is None:
            return
        # From the measurement's stamp to the command on the wire (as before the state message).
        latency_ns = (
            self.command_wall_ns - sample.stamp_ns if self.params.mode == 'realtime' else 0
        )
        assert self.command_done_ns is not None  # _publish set it
        compute_ns = self.command_done_ns - started_ns
        if self.params.mode == 'realtime' and latency_ns > self.period_ns:
            self.late += 1
            self.log.warn(
                'late',
                lambda: (
                    f'late sample: command {latency_ns / 1e3:.0f} us after its measurement '
                    f'(late {self.late}, missed {self.assembly.missed})'
                ),
            )
        self.timing.append((self.received_ns, sample.stamp_ns, latency_ns, compute_ns))

    def _publish(self, sample: ControlSample, started_ns: int | None, state: bool = True) -> None:
        """current_command and controller/state for one sample (NaN where the law did not run)."""
        changed = sample.status != self.status
        self.status = Status(sample.status)
        if sample.command:  # (a sample the joint already has a command for: the state only)
            self.cmd_hold.publish(
                self.encode_command(
                    {
                        'header.stamp': sample.stamp_ns,
                        'header.frame_id': '',
                        'current_a': float(sample.current_a),
                        'safe_stop': bool(sample.safe_stop),
                    }
                )
            )
        self.command_done_ns = time.perf_counter_ns()
        self.command_wall_ns = self.stamp_clock.now_ns()
        if state:
            self._publish_state(sample, started_ns, changed)
            self.goals.after_sample(sample)  # after both went out: off the command's latency

    def _publish_state(self, sample: ControlSample, started_ns: int | None, changed: bool) -> None:
        """controller/state of one sample, when someone listens and the decimator admits it."""
        if not (
            self.state_pub.get_subscription_count()  # nobody listens: neither filled nor sent
            and self.state_decimator.admit(sample.stamp_ns, force=changed)
        ):
            return
        assert self.command_done_ns is not None  # _publish set it
        compute_s = 0.0 if started_ns is None else (self.command_done_ns - started_ns) * 1e-9
        self.state_pub.publish(
            self.encode_state(
                controller_state_fields(
                    sample,
                    sample.stamp_ns,
                    self.params.name,
                    compute_s,
                    self.late,
                    self.assembly.missed,
                )
            )
        )


def main(argv=None) -> int:
    """Entry point of ``ros2 run actuator_controller controller_node``."""
    return run_node(
        'controller_node',
        'PP-NFTSMC-ESO joint controller (PI, SMC-ESO, NFTSMC-ESO by parameter).',
        ControllerNode,
        NODE_NAME,
        argv,
    )


if __name__ == '__main__':
    raise SystemExit(main())
