# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The one joint node: the joint side of the loop for any ``actuator_core.joint.Joint``.

The simulated plant (actuator_plant) and the CiA 402 driver (actuator_cia402) are small
factories of this node; everything their contract has in common lives here once:

  publishes  joint_states (sensor_msgs/JointState: name, position, effort at the joint shaft;
             stamp = the sample instant t_k on a grid of ``sample_time_s``)
  publishes  /clock (rosgraph_msgs/Clock), mode 'sim' only (joints that support sim time)
  subscribes current_command (actuator_msgs/CurrentCommand)

A command passes the command binding (``actuator_core.binding.CommandBinding``: it must answer
a sample this node produced within the command timeout, the newest or one of the 9 before
(``late_window_samples``), once, valid for the timeout from that sample; a safe stop any of the
last 100), the one-publisher guard
and the ``CommandGate`` (finite, within the current limit, safe_stop, timeout, the one brake
policy) under one lock, since the executor thread offers and the sampling thread holds.

mode 'realtime': a sampling thread sleeps on an absolute grid of the monotonic clock (ages
and sleeps never see a wall-clock step; stamps are the system time of sample 0 plus k periods)
and runs one cycle per sample: the gate's hold is written to the joint, then the joint is read.
A joint that replays missed samples (a simulation) integrates each one after a stall; a real
joint skips them, as ros2_control's loop does. mode 'sim': the node owns /clock and steps in
lockstep: it publishes sample k and waits for the command answering it.
A joint that reports a fault, a soft limit crossed or a stale loop (``stop_on_stale_loop``)
ends control at once: the gate closes and the joint's ``end_control`` makes it take 0 A and
the brake (a synchronous drive through braked cycles), the log says what the joint did; the
supervision tick then takes the node through its own deactivation (a fault: on through error
processing to unconfigured), with the reason logged.
"""

from __future__ import annotations

import threading
import time
from typing import Optional

from rclpy.clock import Clock, ClockType
from rclpy.lifecycle import LifecycleState, TransitionCallbackReturn
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState

from actuator_core import clock as stamp_time
from actuator_core.binding import CommandBinding
from actuator_core.gate import CommandGate, Held
from actuator_core.joint import (
    CommandFreshness,
    Joint,
    JointError,
    JointSettings,
    SoftLimits,
)
from actuator_core.limits import CYCLE_LATENESS_MAX_FRACTION
from actuator_core.sample_log import SampleLog
from actuator_core.timing import period_ns, stamp_to_ns
from actuator_msgs.msg import CurrentCommand
from actuator_ros.diagnostics import NodeDiagnostics
from actuator_ros.guard import GraphGuard
from actuator_ros.joint_report import JointReport
from actuator_ros.node import ManagedNode
from actuator_ros.parameters import (
    TIMING_LOG_DESCRIPTION,
    ParameterError,
    declare_output_path,
    declare_shared,
    declare_spec_parameters,
)
from actuator_ros.qos import control_qos
from actuator_ros.wire_io import codec, subscribe_views

#: Stamp of sample 0 in sim mode [ns] (the plant's /clock starts here).
SIM_START_NS = 1_000_000_000
#: Wall time the graph must have been ready before sampling starts [ns].
SETTLE_NS = 500_000_000
#: Longest wait for the sampling thread at a stop [s]: it may be ending control (a drive's
#: braked cycles last up to its state timeout).
SAMPLER_JOIN_TIMEOUT_S = 10.0


class JointNode(JointReport, ManagedNode):
    """Timing, gate, checks and lifecycle of one joint; subclasses say which joint."""

    #: Description of the node for ``--help`` and logs.
    summary = 'joint'

    def __init__(self, node_name: str, settings=None, **node_kwargs) -> None:
        """Declare and check every parameter; nothing is built before configure."""
        self.joint: Optional[Joint] = None
        super().__init__(node_name, **({'settings': settings} if settings else {}), **node_kwargs)

    # --- what a joint kind implements --------------------------------------------------------
    def load_joint_parameters(self) -> None:
        """Declare (or read again) the joint kind's own parameters; raise ParameterError."""

    def make_joint(self) -> Joint:
        """Build the joint from the parameters (called at configure)."""
        raise NotImplementedError

    def build_extras(self) -> None:
        """Create the joint kind's own topics (plant/truth); called at configure."""

    def publish_extras(self, stamp_ns: int) -> None:
        """Publish the joint kind's own messages for the sample just published (its stamp)."""

    def drop_extras(self) -> None:
        """Destroy what ``build_extras`` created."""

    # --- parameters ----------------------------------------------------------------------------
    def load_parameters(self) -> None:
        """Declare the common settings (JointSettings), mode, timing log, then the joint's own."""
        self.mode = declare_shared(self, 'mode')
        if self.get_parameter('use_sim_time').value:
            raise ParameterError(
                "parameter 'use_sim_time' must be false for a joint: it is the time source "
                '(system clock in realtime, /clock in sim)'
            )
        self.cfg: JointSettings = declare_spec_parameters(self, JointSettings)
        self.timing_log = declare_output_path(self, 'timing_log', TIMING_LOG_DESCRIPTION)
        self.load_joint_parameters()

    # --- lifecycle -------------------------------------------------------------------------------
    def build(self) -> None:
        """Joint (configured), gate, window, topics and the 10 Hz supervision timer."""
        cfg = self.cfg
        self.joint = self.make_joint()
        if self.mode == 'sim' and not self.joint.supports_sim_time:
            raise ParameterError(f"mode 'sim' needs a simulated joint; {self.joint.kind} has none")
        try:
            for note in self.joint.configure():
                self.get_logger().warning(note)
        except JointError:
            self.joint = None
            raise
        self.period_ns = period_ns(cfg.sample_time_s)
        self.late_cycle_ns = round(CYCLE_LATENESS_MAX_FRACTION * self.period_ns)
        self.gate = CommandGate(cfg.current_limit_a, cfg.command_timeout_s, cfg.brake_delay_s)
        self.gate_lock = threading.Lock()
        self.binding = CommandBinding(self.period_ns)
        self.soft_limits = SoftLimits(cfg)
        self.freshness = CommandFreshness(
            max(1, round(cfg.fresh_command_window_s / cfg.sample_time_s)),
            cfg.fresh_command_share_min,
        )
        qos = control_qos(self.mode)
        self.state_pub = self.create_lifecycle_publisher(JointState, 'joint_states', qos)
        self.clock_pub = (
            self.create_lifecycle_publisher(ClockMsg, '/clock', 10) if self.mode == 'sim' else None
        )
        self.guard = GraphGuard(self, self.on_conflict)
        self.command_sub = subscribe_views(
            self,
            CurrentCommand,
            'current_command',
            self.on_command,
            qos,
            event_callbacks=self.guard.callbacks('current_command'),
        )
        self.build_extras()
        self.wall = Clock(clock_type=ClockType.STEADY_TIME)
        # Per published sample: stamp, wall ns at publication, stamp of the command held over the
        # preceding interval (-1: none, or 0 A after a timeout). Written to timing_log (.npz).
        self.samples_log = SampleLog(('stamp_ns', 'published_wall_ns', 'held_command_stamp_ns'))
        self.encode_joint_state = codec(JointState).encode
        self.encode_clock = codec(ClockMsg).encode
        self.timer = self.create_timer(0.1, self.on_tick, clock=self.wall)
        self._reset_run()
        self.diagnostics = NodeDiagnostics(
            self,
            self.health_monitor(),
            self.health,
            stamp_ns=(lambda: max(self.published_ns, 0)) if self.mode == 'sim' else None,
        )

    def _reset_run(self) -> None:
        """Reset the sampling state for a new run (configure, and each activate)."""
        self.held = self.gate.hold(0)
        self.sampler: Optional[threading.Thread] = None
        self.stop_sampling = threading.Event()
        self.start_ns: Optional[int] = None  # stamp of sample 0 [ns]
        self.start_mono_ns = 0  # monotonic time of sample 0 [ns] (realtime)
        self.sample_index = -1  # index of the newest sample read
        self.published_ns = -1  # stamp of the newest published sample
        self.waiting_since_ns: Optional[int] = None  # sim: steady time sample k was published
        self.settle_until_ns: Optional[int] = None
        self.conflict = bool(self.guard.conflict)  # more than one publisher on current_command
        self.stopped_reason = ''  # why control ended on the joint side (fault, soft limit)
        self.ending = False  # the joint is stopping (end_control) after control ended
        self.fault = ''  # a joint fault: error processing follows
        self.lockstep_timeouts = 0
        self.skipped_cycles = 0  # realtime, a real joint: cycles the host was too late to run
        self.longest_stall_cycles = 0  # the most cycles one stall skipped
        self.lost_feedback = 0  # cycles the joint gave no sample for (its read returned None)
        self.joint_warnings = 0  # what the joint noticed without ending control (logged)
        self.refused = 0
        self.binding.reset()
        self.soft_limits.reset()
        self.freshness.reset()

    def start(self) -> None:
        """Activate the joint and open the gate; sampling starts once the graph is ready."""
        self._reset_run()
        for note in self._joint.activate():
            self.get_logger().warning(note)
        with self.gate_lock:
            self.gate.activate()

    def stop(self) -> None:
        """0 A and the brake from now on; sampling stops; the joint is deactivated calmly."""
        with self.gate_lock:
            self.gate.deactivate()
        self.stop_sampling.set()
        if self.sampler is not None and self.sampler is not threading.current_thread():
            self.sampler.join(timeout=SAMPLER_JOIN_TIMEOUT_S)
        self._joint.write(0.0, True)
        for note in self._joint.deactivate():
            self.get_logger().warning(note)
        self.held = self.gate.hold(0)  # 0 A and the brake: /diagnostics says so from now on
        self._log_warnings()
        what = self._joint.describe()
        if what:
            self.get_logger().info(f'{self.summary} stopped: {what}')
        self.close_log()

    def drop(self) -> None:
        """Destroy the topics and the timer; communication with the joint down."""
        self.destroy_timer(self.timer)
        self.destroy_subscription(self.command_sub)
        for pub in (self.state_pub, self.clock_pub):
            if pub is not None:
                self.destroy_lifecycle_publisher(pub)
        self.drop_extras()
        self.diagnostics.destroy()
        for note in self._joint.close():
            self.get_logger().warning(note)
        self.joint = None

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Configure; a joint that cannot be brought up (JointError) leaves it unconfigured."""
        try:
            return super().on_configure(state)
        except JointError as exc:
            self.get_logger().error(f'configure failed: {self.summary}: {exc}')
            return TransitionCallbackReturn.FAILURE

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Activate; a joint that refuses (JointError) leaves the node inactive."""
        try:
            return super().on_activate(state)
        except JointError as exc:
            self.active = False
            self.get_logger().error(f'activate refused: {exc}')
            return TransitionCallbackReturn.FAILURE

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Deactivate; ERROR (error processing) when a joint fault ended control."""
        result = super().on_deactivate(state)
        return TransitionCallbackReturn.ERROR if self.fault else result

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Error processing after a joint fault: log it, leave the joint safe, unconfigured.

        The topics, the timer and the joint's connection stay until the next configure or the
        exit (``_drop`` there): this runs in the supervision timer's own callback, and
        destroying that timer and the subscriptions while the events executor dispatches them
        ended the process with SIGSEGV (2 of 14 conflict attacks on the CiA 402 joint here).
        """
        if self.fault:
            self.get_logger().error(
                f'{self.summary} fault: {self.fault}; measurements stopped, 0 A, brake engaged'
            )
            self._stop()
            return TransitionCallbackReturn.SUCCESS
        return super().on_error(state)

    # --- supervision (executor thread, 10 Hz) ------------------------------------------------
    def on_tick(self) -> None:
        """Joint warnings; start once the graph is ready; sim lockstep watchdog; control ended."""
        self._log_warnings()
        if not self.active:
            return
        if self.stopped_reason:  # the node's own deactivation (a fault: error processing next)
            if not self.ending:  # once the joint has stopped (and said so)
                self._internal_transition = True
                try:
                    self.trigger_deactivate()
                finally:
                    self._internal_transition = False
            return
        if self.start_ns is None:
            self._start_when_ready()
            return
        if (
            self.mode == 'sim'
            and self.waiting_since_ns is not None
            and self.wall.now().nanoseconds - self.waiting_since_ns
            > self.cfg.lockstep_timeout_s * 1e9
        ):
            # The lockstep is broken (a node that never answers: a missed activation, a crash):
            # stepping without commands would run the plant open loop at a step per timeout.
            self.lockstep_timeouts += 1
            self.waiting_since_ns = None
            self._end_control(
                f'sim: no command for sample {self.sample_index} within '
                f'{self.cfg.lockstep_timeout_s:g} s of wall time (lockstep_timeout_s)',
                fault=False,
            )

    def on_conflict(self, conflict: str) -> None:
        """Take a change of matched publishers: more than one on current_command, 0 A, brake."""
        if bool(conflict) == self.conflict:
            return
        self.conflict = bool(conflict)
        if self.conflict:
            self.get_logger().error(
                f'{conflict}: refusing every command (0 A, brake) until one is left'
            )
            if self.configured:
                with self.gate_lock:
                    self.gate.offer(0.0, self.published_ns, True, self._gate_now_ns())
        else:
            self.get_logger().warning('one publisher on current_command again: commands accepted')

    def _start_when_ready(self) -> None:
        """Start sampling once the expected subscribers and publisher have been there 0.5 s."""
        n = self.cfg.wait_for_subscribers
        ready = self.state_pub.get_subscription_count() >= n and (
            n == 0 or self.count_publishers('current_command') >= 1
        )
        now = self.wall.now().nanoseconds
        if not ready:
            self.settle_until_ns = None
        elif self.settle_until_ns is None:
            self.settle_until_ns = now + SETTLE_NS
        elif now >= self.settle_until_ns:
            self._start_sampling()

    def _start_sampling(self) -> None:
        """Fix the stamp of sample 0 and read it (realtime: start the sampling thread)."""
        self.get_logger().info('sampling started')
        # stamp time anchored on the wall clock once: the grid then counts monotonic periods, so a
        # later step of the wall clock moves no stamp (actuator_core.clock); in sim it times the
        # log's publications only (the stamps are sim time)
        self.stamp_clock = stamp_time.StampClock(stamp_time.Clock())
        if self.mode == 'sim':
            self.start_ns = SIM_START_NS
            self._cycle(0, write=False)
            return
        self.start_mono_ns = time.monotonic_ns() + self.period_ns
        self.start_ns = self.stamp_clock.at(self.start_mono_ns)
        self.stop_sampling.clear()
        self.sampler = threading.Thread(target=self._sampling_loop, name='sampling', daemon=True)
        self.sampler.start()

    # --- the cycle ---------------------------------------------------------------------------
    def _gate_now_ns(self) -> int:
        """Return the gate's clock: monotonic in real time, the newest sample's stamp in sim."""
        return self.published_ns if self.mode == 'sim' else time.monotonic_ns()

    def _sampling_loop(self) -> None:
        """Realtime: sleep to the next instant of the monotonic grid, run the due cycles.

        A real joint samples when its cycle runs, so a cycle runs at its instant or not at all:
        one that would start more than ``CYCLE_LATENESS_MAX_FRACTION`` of a period late is
        skipped, and the stamp of every sample stays the instant it was taken at.

        Ends with control (a fault, a soft limit, a stale loop): a cycle then reads nothing, so
        the grid would not advance and this SCHED_FIFO thread would spin until deactivation.
        """
        try:
            next_k = 0  # the next instant a cycle may run at (a real joint skips late ones)
            while not (self.finished or self.stopped_reason or self.stop_sampling.is_set()):
                next_k = max(next_k, self.sample_index + 1)
                wait_ns = self.start_mono_ns + next_k * self.period_ns - time.monotonic_ns()
                if wait_ns > 0:
                    time.sleep(wait_ns * 1e-9)
                since_start_ns = time.monotonic_ns() - self.start_mono_ns
                due = since_start_ns // self.period_ns
                if self._joint.replays_missed:  # a simulation loses no time: each sample in turn
                    while self.sample_index < due and self._cycle(self.sample_index + 1):
                        pass
                elif since_start_ns - due * self.period_ns > self.late_cycle_ns:
                    next_k = due + 1  # too late for this instant's cycle: the next one runs
                elif due > self.sample_index:  # a real joint: missed cycles are skipped
                    skipped = due - self.sample_index - 1
                    if skipped:
                        self._host_stalled(skipped)
                    self._cycle(due)
        except Exception as exc:  # noqa: BLE001 - reported by run_node, never lost with the thread
            self.error = f'sampling thread failed: {exc!r}'
            self.finished = True

    def _cycle(self, k: int, write: bool = True) -> bool:
        """Write the gate's hold to the joint, read sample k, publish it; False: control ended."""
        if self.stopped_reason:
            return False
        if write:
            instant = (
                self.start_mono_ns + self.sample_index * self.period_ns
                if self.mode == 'realtime' and self._joint.replays_missed
                else self._gate_now_ns()
            )
            with self.gate_lock:
                self.held = self.gate.hold(instant)
            if self.held.reason == 'command timeout':
                self.log.warn('command_timeout', lambda: 'commands stopped: 0 A, then the brake')
            self._joint.write(self.held.current_a, self.held.brake)
            if self._judge_freshness():
                return False
        assert self.start_ns is not None  # sampling started
        stamp_ns = self.start_ns + k * self.period_ns
        sample = self._joint.read(stamp_ns)
        self.sample_index = k
        if sample is None:
            self.lost_feedback += 1
            return True  # lost feedback: the joint kind says why; nothing to publish
        problem = sample.fault or self.soft_limits.check(stamp_ns, sample.position_rad)
        if problem:
            self._end_control(problem, fault=bool(sample.fault))
            return False
        return self._publish(sample)

    def _judge_freshness(self) -> bool:
        """Count whether the command just written answered one of the two newest samples.

        Return True when control ended on it (stop_on_stale_loop).
        """
        newest = self.published_ns
        fresh = newest >= 0 and self.held.command_stamp_ns >= newest - self.period_ns
        change = self.freshness.add(fresh)
        if change == 'degraded':
            reason = f'loop too slow: {self.freshness.describe()}'
            if self.cfg.stop_on_stale_loop:
                self._end_control(reason, fault=False)
                return True
            self.get_logger().warning(f'{reason}; /diagnostics warns while it lasts')
        elif change == 'healthy':
            self.get_logger().info(f'loop healthy again: {self.freshness.describe()}')
        return False

    def _end_control(self, reason: str, fault: bool) -> None:
        """0 A and the brake now (the joint's end_control), no more samples; log what it did.

        The supervision tick then deactivates the node; a fault goes on to error processing.
        """
        with self.gate_lock:
            self.gate.deactivate()
            self.held = Held(0.0, -1, True, f'control ended: {reason}')
        self.stopped_reason, self.ending = reason, True
        if fault:
            self.fault = reason
        try:
            what = self._joint.end_control(reason)
        finally:
            self.ending = False
        self.get_logger().error(f'control ended: {reason}; {what}')
        if self.cfg.stop_after_s:  # a bounded run cannot reach its end: it failed, and exits
            self.error = f'the run of {self.cfg.stop_after_s:g} s ended early: {reason}'
            self.finished = True

    def _publish(self, sample) -> bool:
        """Publish /clock (sim), the measurement and the joint kind's extras; False when done."""
        stop_after = self.cfg.stop_after_s
        if stop_after and sample.stamp_ns - self.start_ns >= stop_after * 1e9:
            if not self.finished:
                self.get_logger().info(f'run of {stop_after} s complete')
            self.finished = True
            self.waiting_since_ns = None
            return False
        if self.clock_pub is not None:
            self.clock_pub.publish(self.encode_clock({'clock': sample.stamp_ns}))
            self.waiting_since_ns = self.wall.now().nanoseconds
        self.published_ns = sample.stamp_ns
        self.binding.produced(sample.stamp_ns)
        self.state_pub.publish(
            self.encode_joint_state(
                {
                    'header.stamp': sample.stamp_ns,
                    'header.frame_id': '',
                    'name': (self.cfg.joint_name,),
                    'position': (float(sample.position_rad),),
                    'velocity': (),
                    'effort': (float(sample.effort_nm),),
                }
            )
        )
        published = self.stamp_clock.now_ns()
        self.samples_log.append((sample.stamp_ns, published, self.held.command_stamp_ns))
        self.publish_extras(sample.stamp_ns)
        return True

    def _sim_step(self) -> None:
        """sim: integrate one sample with what the gate holds and publish the next."""
        self.waiting_since_ns = None
        self._cycle(self.sample_index + 1)

    # --- commands ----------------------------------------------------------------------------
    def on_command(self, msg: CurrentCommand) -> None:
        """Window, guard, then the gate; sim: step when the command answers the waiting sample."""
        if not self.active or self.start_ns is None or self.stopped_reason:
            return  # not sampling, or control ended (said once, in _end_control)
        stamp_ns = stamp_to_ns(msg.header.stamp)
        # Values before stamps: a non-finite or out-of-range current gives 0 A and the brake
        # (the gate's refusal) whatever sample it claims; only a valid one is bound to a sample.
        valid = bool(self.gate.valid(msg.current_a))
        refusal = self.binding.check(stamp_ns, msg.safe_stop) if valid else ''
        if refusal:
            self.refused += 1
            self.log.error('command_stamp', lambda: refusal)
            return
        if self.conflict and valid:
            self.log.error(
                'conflict', lambda: 'command refused: more than one publisher on current_command'
            )
            return
        valid_from_ns = self.binding.valid_from_ns(stamp_ns, msg.safe_stop, self._gate_now_ns())
        with self.gate_lock:
            offer_refusal = self.gate.offer(msg.current_a, stamp_ns, msg.safe_stop, valid_from_ns)
        if offer_refusal:
            self.log.error('bad_command', lambda: offer_refusal)
        if (
            self.mode == 'sim'
            and stamp_ns == self.published_ns
            and self.waiting_since_ns is not None
        ):
            self._sim_step()
