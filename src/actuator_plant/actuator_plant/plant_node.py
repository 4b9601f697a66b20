"""Simulated joint node: integrates the joint model and publishes only what a position sensor gives.

Topics (the contract a hardware driver implements, README "Nodes and topic contract"):
  publishes  joint_states (sensor_msgs/JointState: name, position; stamp = sample time t_k)
  publishes  plant/truth (actuator_msgs/PlantTruth), simulation only
  publishes  /clock (rosgraph_msgs/Clock), mode 'sim' only
  subscribes current_command (actuator_msgs/CurrentCommand)

mode 'realtime': a sampling thread wakes on an absolute 1 kHz grid of the system clock (as
ros2_control's loop does) and samples the joint; the current held over each sample is the
newest valid command, or zero once commands are older than command_timeout_s.
mode 'sim': the node owns /clock and steps in lockstep: it publishes sample k and waits for
the command answering sample k (paired by stamp) before integrating to k+1, so the run is
deterministic and as fast as the three processes allow.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import replace

from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from actuator_core import limits
from actuator_ros.runtime import RateLimitedLog, MODES, ParameterError, control_qos, declare_choice, declare_number, \
    declare_spec_parameters, ns_to_stamp, run_node
from actuator_core.sample_log import SampleLog
from actuator_core.timing import period_ns, stamp_to_ns
from actuator_msgs.msg import CurrentCommand, PlantTruth
from actuator_plant.model import JointPlant, PlantParameters, WorkingCondition
from builtin_interfaces.msg import Time
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState

CONDITIONS = ('deep_sea', 'lab', 'depth', 'custom')




class PlantNode(Node):
    """The simulated joint behind the sensor/command topic contract."""

    def __init__(self) -> None:
        """Declare and check parameters, build the model, start sampling."""
        super().__init__('actuator_plant')
        self.log = RateLimitedLog(self.get_logger())
        self.mode = declare_choice(self, 'mode', 'realtime', MODES, 'realtime: wall-clock 1 kHz; sim: lockstep /clock')
        if self.get_parameter('use_sim_time').value:
            raise ParameterError("parameter 'use_sim_time' must be false for the plant: it is the time source "
                                 "(system clock in realtime, /clock in sim)")
        condition = declare_choice(self, 'working_condition', 'deep_sea', CONDITIONS,
                                   'deep_sea: 10 MPa, 2 degC; lab: 0 MPa, 25 degC; depth: depth_m and '
                                   'condition.temperature_c; custom: condition.pressure_pa and condition.temperature_c')
        depth = declare_number(self, 'depth_m', 1000.0, 0.0, 11000.0, 'm', 'water depth for working_condition depth')
        params = declare_spec_parameters(self, PlantParameters)
        if condition == 'deep_sea':
            params = _with_condition(params, WorkingCondition.deep_sea())
        elif condition == 'lab':
            params = _with_condition(params, WorkingCondition.lab())
        elif condition == 'depth':
            params = _with_condition(params, WorkingCondition.at_depth(depth, params.condition.temperature_c))
        self.dt_s = declare_number(self, 'sample_time_s', limits.SAMPLE_TIME_S, *limits.SAMPLE_TIME_RANGE_S, 's', 'sensor sample period')
        self.command_timeout_s = declare_number(self, 'command_timeout_s', limits.COMMAND_TIMEOUT_S, *limits.TIMEOUT_RANGE_S, 's',
                                                'realtime: current drops to zero when commands are older')
        self.command_timeout_ns = int(round(self.command_timeout_s * 1e9))
        self.current_limit_a = declare_number(self, 'current_limit_a', limits.CURRENT_LIMIT_A, *limits.CURRENT_LIMIT_RANGE_A, 'A',
                                              'commands beyond +-this are refused (zero applied)')
        self.lockstep_timeout_s = declare_number(self, 'lockstep_timeout_s', 2.0, 0.01, 600.0, 's',
                                                 'sim: wall time to wait for a command before stepping with 0 A')
        self.wait_for_subscribers = declare_number(
            self, 'wait_for_subscribers', 0, 0, 100, '',
            'start sampling only once joint_states has this many subscribers (and current_command a publisher)')
        self.stop_after_s = declare_number(self, 'stop_after_s', 0.0, 0.0, 1.0e6, 's',
                                           'end the run (exit 0) after this much simulated time; 0 runs until stopped')
        self.joint_name = self.declare_parameter('joint_name', 'joint').value
        self.timing_log = self.declare_parameter('timing_log', '').value
        # Per published sample: stamp, wall ns at publication, stamp of the command held over the
        # preceding interval (-1: none yet / zero after a timeout). Written to timing_log (.npz).
        self.samples_log = SampleLog(('stamp_ns', 'published_wall_ns', 'held_command_stamp_ns'))
        self.held_stamp_ns = -1           # stamp of the command held over the running sample
        self.plant = JointPlant(params, self.dt_s, position_rad=declare_number(
            self, 'initial_position_rad', 0.0, -100.0, 100.0, 'rad', 'joint angle at sample 0'))
        self.period_ns = period_ns(self.dt_s)
        qos = control_qos(self.mode)
        self.state_pub = self.create_publisher(JointState, 'joint_states', qos)
        self.truth_pub = self.create_publisher(PlantTruth, 'plant/truth', qos)
        self.clock_pub = self.create_publisher(ClockMsg, '/clock', 10) if self.mode == 'sim' else None
        self.create_subscription(CurrentCommand, 'current_command', self.on_command, qos)
        self.wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.finished = False             # read by run_node: the run is over
        self.current_a = 0.0              # current held over the running sample
        # realtime: the newest valid command as one tuple (current [A], stamp [ns], receive time
        # [ns, system clock]), so the sampling thread never sees one command's current with another's stamp.
        self.command: tuple[float, int, int | None] = (0.0, -1, None)
        self.command_stale = False        # realtime: commands have timed out
        self.sampler: threading.Thread | None = None
        self.stop_sampling = threading.Event()
        self.error: str | None = None     # read by run_node: the run failed
        self.start_ns = None              # stamp of sample 0 [ns]
        self.rejected_commands = 0
        self.timeouts = 0
        self.waiting_since_ns = None      # sim: steady time sample k was published
        self.settle_until_ns = None       # start once the graph has been ready this long
        self.next_sample = 0              # realtime: index of the next sample to publish
        self.joint_state = JointState(name=[self.joint_name], position=[0.0])
        self.truth = PlantTruth()
        self.truth.pressure_pa = float(params.condition.pressure_pa)
        self.truth.temperature_degc = float(params.condition.temperature_c)
        self.truth.viscosity_pa_s = float(self.plant.constants.viscosity_pa_s)
        self.get_logger().info(
            f'{self.mode} mode, {condition}: P = {params.condition.pressure_pa / 1e6:.2f} MPa, '
            f'T = {params.condition.temperature_c:.1f} degC, mu = {self.plant.constants.viscosity_pa_s * 1e3:.1f} mPa s')
        # Start-up (both modes) and the sim lockstep watchdog: 10 Hz is plenty. Realtime sampling
        # runs on its own thread (see _sampling_loop).
        self.timer = self.create_timer(0.1, self.on_tick, clock=self.wall)

    # --- sampling -------------------------------------------------------------------------
    def _graph_ready(self) -> bool:
        """Everyone expected has joined (only checked before sample 0)."""
        return (self.state_pub.get_subscription_count() >= self.wait_for_subscribers
                and (self.wait_for_subscribers == 0 or self.count_publishers('current_command') >= 1))

    def _start(self) -> None:
        """Fix the stamp of sample 0 and publish it (realtime: start the sampling thread).

        realtime: each stamp is the scheduled sampling instant on the grid, never later than
        the actual sampling; whatever the thread wakes late by shows up in the measured
        latency, where it belongs.
        """
        self.get_logger().info('sampling started')
        if self.mode == 'sim':
            self.start_ns = 1_000_000_000
            self._publish_sample()
        else:
            self.start_ns = time.time_ns() + self.period_ns
            self.sampler = threading.Thread(target=self._sampling_loop, name='sampling', daemon=True)
            self.sampler.start()

    def on_tick(self) -> None:
        """10 Hz wall timer: start once the graph is ready; sim: lockstep watchdog."""
        if self.start_ns is None:
            if self._graph_ready():
                if self.settle_until_ns is None:
                    self.settle_until_ns = self.wall.now().nanoseconds + 500_000_000
                elif self.wall.now().nanoseconds >= self.settle_until_ns:
                    self._start()
            return
        if self.mode == 'sim' and self.waiting_since_ns is not None and \
                self.wall.now().nanoseconds - self.waiting_since_ns > self.lockstep_timeout_s * 1e9:
            self.timeouts += 1
            self.log.warn('lockstep_timeout', lambda: f'sim: no command for sample {self.plant.sample_index} within '
                                   f'{self.lockstep_timeout_s} s; stepping with 0 A')
            self._advance(0.0)

    def _sampling_loop(self) -> None:
        """realtime: sleep until the next instant of the sample grid, sample, repeat (ros2_control's loop).

        One thread wake per sample, against two for an rclpy timer (its timer thread, then the
        executor); it inherits the process's SCHED_FIFO priority. An exception ends the run
        with the error (run_node exits 1) instead of leaving a node that no longer samples.
        """
        try:
            while not self.finished and not self.stop_sampling.is_set():
                wait_ns = self.start_ns + self.next_sample * self.period_ns - time.time_ns()
                if wait_ns > 0:
                    time.sleep(wait_ns * 1e-9)
                self._realtime_tick()
        except Exception as exc:  # noqa: BLE001 - reported by run_node, never lost with the thread
            self.error = f'sampling thread failed: {exc!r}'
            self.finished = True

    def _realtime_tick(self) -> None:
        """Integrate every whole period elapsed since the last sample, then publish the newest sample.

        After a stall (the process did not run for several periods) the samples it covered
        are integrated one by one, and only the newest is published (the controller counts
        the gap as missed samples). Each sample holds the newest command unless that is older
        than command_timeout_s at the sample's start, as a drive's watchdog would see it in
        real time: a 40 ms stall holds the current for 10 ms, then 0 A, not 0 A throughout.
        """
        due = (time.time_ns() - self.start_ns) // self.period_ns
        if due < self.next_sample:
            return
        current, stamp_ns, received_ns = self.command
        while self.plant.sample_index < due:
            sample_start_ns = self.start_ns + self.plant.sample_index * self.period_ns
            stale = received_ns is not None and sample_start_ns - received_ns > self.command_timeout_ns
            if stale and not self.command_stale:
                self.timeouts += 1
                self.log.warn('command_timeout', lambda: 'commands stopped: current set to 0 A')
            self.command_stale = stale
            self.current_a, self.held_stamp_ns = (0.0, -1) if stale else (current, stamp_ns)
            self.plant.step(self.current_a)
        self.next_sample = due + 1
        self._publish_sample()

    def _advance(self, current_a: float) -> None:
        """sim: integrate one sample with ``current_a`` and publish the next."""
        self.current_a = current_a
        self.plant.step(current_a)
        self._publish_sample()

    def _publish_sample(self) -> None:
        """Publish /clock (sim), the measurement and the ground truth of the current sample."""
        if self.stop_after_s and self.plant.sample_index * self.period_ns >= self.stop_after_s * 1e9:
            if not self.finished:
                self.get_logger().info(f'run of {self.stop_after_s} s complete')
            self.finished = True
            self.waiting_since_ns = None
            return
        stamp = ns_to_stamp(self.start_ns + self.plant.sample_index * self.period_ns)
        if self.clock_pub is not None:
            self.clock_pub.publish(ClockMsg(clock=stamp))
            self.waiting_since_ns = self.wall.now().nanoseconds
        self.joint_state.header.stamp = stamp
        self.joint_state.position[0] = float(self.plant.position_rad)
        self.state_pub.publish(self.joint_state)
        self.samples_log.append((stamp_to_ns(stamp), time.time_ns(), self.held_stamp_ns))
        self._publish_truth(stamp)

    def _publish_truth(self, stamp: Time) -> None:
        """Ground truth at t_k with the current held over the preceding sample."""
        parts = self.plant.truth(self.current_a)
        f, m = parts.forces, self.truth
        m.header.stamp = stamp
        m.position_rad = float(self.plant.position_rad)
        m.velocity_rad_s = float(self.plant.velocity_rad_s)
        m.acceleration_rad_s2 = float(parts.acceleration_rad_s2)
        m.current_a = float(self.current_a)
        m.disturbance_rad_s2 = float(parts.disturbance_rad_s2)
        m.parametric_rad_s2 = float(parts.parametric_rad_s2)
        m.stirring_rad_s2 = float(parts.stirring_rad_s2)
        m.external_rad_s2 = float(parts.external_rad_s2)
        m.seal_rad_s2 = float(parts.seal_rad_s2)
        m.stirring_torque_nm = float(f.stirring_torque_nm)
        m.external_torque_nm = float(f.external_torque_nm)
        m.seal_torque_nm = float(f.seal_torque_nm)
        m.inertia_kg_m2 = float(f.inertia_kg_m2)
        m.torque_constant_nm_a = float(f.torque_constant_nm_a)
        m.viscous_coefficient_nm_s_rad = float(f.viscous_coefficient_nm_s_rad)
        self.truth_pub.publish(m)

    # --- commands -------------------------------------------------------------------------
    def on_command(self, msg: CurrentCommand) -> None:
        """Check a command; realtime: hold it; sim: step when it answers the waiting sample."""
        current = msg.current_a
        if not math.isfinite(current) or abs(current) > self.current_limit_a:
            self.rejected_commands += 1
            self.log.error('bad_command', lambda: f'command {current} A refused (valid: finite, |u| <= {self.current_limit_a} A); '
                                    'applying 0 A')
            current = 0.0
        if self.start_ns is None:
            return
        if self.mode == 'realtime':
            self.command = (current, stamp_to_ns(msg.header.stamp), time.time_ns())
            return
        expected = self.start_ns + self.plant.sample_index * self.period_ns
        if stamp_to_ns(msg.header.stamp) == expected and self.waiting_since_ns is not None:
            self.waiting_since_ns = None
            self.held_stamp_ns = expected
            self._advance(current)

    def close(self) -> None:
        """Stop the sampling thread; log a one-line summary; write the per-sample log if asked."""
        self.stop_sampling.set()
        if self.sampler is not None:
            self.sampler.join(timeout=1.0)
        if self.timing_log:
            self.samples_log.save(self.timing_log)
        self.get_logger().info(
            f'stopped at sample {self.plant.sample_index} (t = {self.plant.time_s:.3f} s); '
            f'refused commands {self.rejected_commands}, command timeouts {self.timeouts}')


def _with_condition(params: PlantParameters, condition: WorkingCondition) -> PlantParameters:
    """The same parameters in another working condition."""
    return replace(params, condition=condition)


def main(argv=None) -> int:
    """Entry point of ``ros2 run actuator_plant plant_node``."""
    return run_node('plant_node', 'Simulated deep-sea oil-filled joint (sensor: angle only).', PlantNode, argv)


if __name__ == '__main__':
    raise SystemExit(main())
