# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Simulated joint node (managed).

It integrates the joint model and publishes only what a position sensor gives.

Topics (the contract a hardware driver implements, README "Nodes and topic contract"):
  publishes  joint_states (sensor_msgs/JointState: name, position; stamp = sample time t_k)
  publishes  plant/truth (actuator_msgs/PlantTruth), simulation only
  publishes  /clock (rosgraph_msgs/Clock), mode 'sim' only
  subscribes current_command (actuator_msgs/CurrentCommand)

The node holds a ``JointPlant`` and the drive's ``CommandGate`` (actuator_core.gate), the same
objects as the offline loop. Commands pass the gate (finite, within the one current limit,
``safe_stop`` honoured, timeout, holding brake) and a stamp check: a command must answer a
sample this node has published. While another node also publishes on current_command, every
command is refused (0 A, brake) until one publisher is left.

mode 'realtime': a sampling thread wakes on an absolute 1 kHz grid of the system clock (as
ros2_control's loop does) and samples the joint; each sample holds what the gate says.
mode 'sim': the node owns /clock and steps in lockstep: it publishes sample k and waits for
the command answering sample k (paired by stamp) before integrating to k+1.
Lifecycle (actuator_ros.node): sampling starts on activate, once the graph is ready; on
deactivate the gate goes to 0 A with the brake and sampling stops.
"""

from __future__ import annotations

import threading
import time
from dataclasses import replace

from rclpy.clock import Clock, ClockType

from actuator_core import limits
from actuator_core.gate import CommandGate
from actuator_core.sample_log import SampleLog
from actuator_core.timing import period_ns, stamp_to_ns
from actuator_msgs.msg import CurrentCommand, PlantTruth
from actuator_plant.model import JointPlant, PlantParameters, WorkingCondition
from actuator_ros.conversions import ns_to_stamp
from actuator_ros.node import ManagedNode
from actuator_ros.parameters import (
    ParameterError,
    declare_choice,
    declare_number,
    declare_output_path,
    declare_spec_parameters,
    declare_text,
)
from actuator_ros.qos import MODES, control_qos
from actuator_ros.runner import run_node
from builtin_interfaces.msg import Time
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState

CONDITIONS = ('deep_sea', 'lab', 'depth', 'custom')
NODE_NAME = 'actuator_plant'


class PlantNode(ManagedNode):
    """The simulated joint behind the sensor/command topic contract."""

    def __init__(self, settings=None) -> None:
        """Declare and check every parameter; nothing is built before configure."""
        self.plant = None
        super().__init__(NODE_NAME, **({'settings': settings} if settings else {}))

    def load_parameters(self) -> None:
        """Declare (or read again at configure) and check every parameter."""
        self.mode = declare_choice(
            self, 'mode', 'realtime', MODES, 'realtime: wall-clock 1 kHz; sim: lockstep /clock'
        )
        if self.get_parameter('use_sim_time').value:
            raise ParameterError(
                "parameter 'use_sim_time' must be false for the plant: it is the time source "
                '(system clock in realtime, /clock in sim)'
            )
        condition = declare_choice(
            self,
            'working_condition',
            'deep_sea',
            CONDITIONS,
            'deep_sea: 10 MPa, 2 degC; lab: 0 MPa, 25 degC; depth: depth_m and '
            'condition.temperature_c; custom: condition.pressure_pa and condition.temperature_c',
        )
        depth = declare_number(
            self, 'depth_m', 1000.0, 0.0, 11000.0, 'm', 'water depth for working_condition depth'
        )
        params = declare_spec_parameters(self, PlantParameters)
        chosen = {
            'deep_sea': WorkingCondition.deep_sea,
            'lab': WorkingCondition.lab,
            'depth': lambda: WorkingCondition.at_depth(depth, params.condition.temperature_c),
            'custom': lambda: params.condition,
        }[condition]()
        self.params = replace(params, condition=chosen)
        self.condition_name = condition
        self.dt_s = declare_number(
            self,
            'sample_time_s',
            limits.SAMPLE_TIME_S,
            *limits.SAMPLE_TIME_RANGE_S,
            's',
            'sensor sample period',
        )
        self.command_timeout_s = declare_number(
            self,
            'command_timeout_s',
            limits.COMMAND_TIMEOUT_S,
            *limits.TIMEOUT_RANGE_S,
            's',
            'the drive applies 0 A with the brake when commands are older',
        )
        self.current_limit_a = declare_number(
            self,
            'current_limit_a',
            limits.CURRENT_LIMIT_A,
            *limits.CURRENT_LIMIT_RANGE_A,
            'A',
            'commands beyond +-this are refused (0 A applied)',
        )
        self.lockstep_timeout_s = declare_number(
            self,
            'lockstep_timeout_s',
            2.0,
            0.01,
            600.0,
            's',
            'sim: wall time to wait for a command before stepping without it',
        )
        self.wait_for_subscribers = declare_number(
            self,
            'wait_for_subscribers',
            0,
            0,
            100,
            '',
            'start sampling only once joint_states has this many subscribers (and '
            'current_command a publisher)',
        )
        self.stop_after_s = declare_number(
            self,
            'stop_after_s',
            0.0,
            0.0,
            1.0e6,
            's',
            'end the run (exit 0) after this much simulated time; 0 runs until stopped',
        )
        self.initial_position_rad = declare_number(
            self,
            'initial_position_rad',
            0.0,
            -limits.POSITION_LIMIT_RAD,
            limits.POSITION_LIMIT_RAD,
            'rad',
            'joint angle at sample 0',
        )
        self.joint_name = declare_text(
            self, 'joint_name', 'joint', 'name of the joint in joint_states'
        )
        self.timing_log = declare_output_path(
            self, 'timing_log', 'per-sample log (.npz) written at shutdown'
        )

    # --- lifecycle -------------------------------------------------------------------------------
    def build(self) -> None:
        """Model, gate, topics and the 10 Hz start-up/watchdog timer; nothing published yet."""
        self.plant = JointPlant(self.params, self.dt_s, position_rad=self.initial_position_rad)
        self.gate = CommandGate(self.current_limit_a, self.command_timeout_s)
        self.period_ns = period_ns(self.dt_s)
        qos = control_qos(self.mode)
        self.state_pub = self.create_lifecycle_publisher(JointState, 'joint_states', qos)
        self.truth_pub = self.create_lifecycle_publisher(PlantTruth, 'plant/truth', qos)
        self.clock_pub = (
            self.create_lifecycle_publisher(ClockMsg, '/clock', 10) if self.mode == 'sim' else None
        )
        self.command_sub = self.create_subscription(
            CurrentCommand, 'current_command', self.on_command, qos
        )
        self.wall = Clock(clock_type=ClockType.STEADY_TIME)
        # Per published sample: stamp, wall ns at publication, stamp of the command held over the
        # preceding interval (-1: none, or 0 A after a timeout). Written to timing_log (.npz).
        self.samples_log = SampleLog(('stamp_ns', 'published_wall_ns', 'held_command_stamp_ns'))
        self.held = self.gate.hold(0)
        self.sampler: threading.Thread | None = None
        self.stop_sampling = threading.Event()
        self.start_ns = None  # stamp of sample 0 [ns]
        self.waiting_since_ns = None  # sim: steady time sample k was published
        self.settle_until_ns = None  # start once the graph has been ready this long
        self.next_sample = 0  # realtime: index of the next sample to publish
        self.published_ns = -1  # stamp of the newest published sample
        self.conflict = False  # more than one publisher on current_command
        self.lockstep_timeouts = 0
        self.joint_state = JointState(name=[self.joint_name], position=[0.0])
        self.truth = PlantTruth(
            pressure_pa=float(self.params.condition.pressure_pa),
            temperature_degc=float(self.params.condition.temperature_c),
            viscosity_pa_s=float(self.plant.constants.viscosity_pa_s),
        )
        self.timer = self.create_timer(0.1, self.on_tick, clock=self.wall)
        c = self.params.condition
        self.get_logger().info(
            f'{self.mode} mode, {self.condition_name}: P = {c.pressure_pa / 1e6:.2f} MPa, T = '
            f'{c.temperature_c:.1f} '
            f'degC, mu = {self.plant.constants.viscosity_pa_s * 1e3:.1f} mPa s; current limit '
            f'{self.current_limit_a} A'
        )

    def start(self) -> None:
        """Open the gate for commands; sampling starts once the graph is ready (on_tick)."""
        self.gate.activate()

    def stop(self) -> None:
        """0 A and the brake from now on; sampling stops."""
        self.gate.deactivate()
        self.stop_sampling.set()
        if self.sampler is not None:
            self.sampler.join(timeout=1.0)
        self.close_log()

    def drop(self) -> None:
        """Destroy the topics and the timer."""
        self.destroy_timer(self.timer)
        self.destroy_subscription(self.command_sub)
        for pub in (self.state_pub, self.truth_pub, self.clock_pub):
            if pub is not None:
                self.destroy_lifecycle_publisher(pub)
        self.plant = None

    # --- sampling --------------------------------------------------------------------------------
    def _graph_ready(self) -> bool:
        """Everyone expected has joined (only checked before sample 0)."""
        return self.state_pub.get_subscription_count() >= self.wait_for_subscribers and (
            self.wait_for_subscribers == 0 or self.count_publishers('current_command') >= 1
        )

    def _start_sampling(self) -> None:
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
            self.stop_sampling.clear()
            self.sampler = threading.Thread(
                target=self._sampling_loop, name='sampling', daemon=True
            )
            self.sampler.start()

    def on_tick(self) -> None:
        """10 Hz wall timer: start once the graph is ready; publisher count.

        Sim lockstep watchdog.
        """
        if not self.active:
            return
        publishers = self.count_publishers('current_command')
        if (publishers > 1) != self.conflict:
            self.conflict = publishers > 1
            if self.conflict:
                self.get_logger().error(
                    f'{publishers} publishers on current_command: refusing every command '
                    '(0 A, brake) until one is left'
                )
                self.gate.offer(0.0, self.published_ns, True, self._now_ns())
            else:
                self.get_logger().warning(
                    'one publisher on current_command again: commands accepted'
                )
        if self.start_ns is None:
            if self._graph_ready():
                if self.settle_until_ns is None:
                    self.settle_until_ns = self.wall.now().nanoseconds + 500_000_000
                elif self.wall.now().nanoseconds >= self.settle_until_ns:
                    self._start_sampling()
            return
        if (
            self.mode == 'sim'
            and self.waiting_since_ns is not None
            and self.wall.now().nanoseconds - self.waiting_since_ns > self.lockstep_timeout_s * 1e9
        ):
            self.lockstep_timeouts += 1
            self.log.warn(
                'lockstep_timeout',
                lambda: (
                    f'sim: no command for sample {self.plant.sample_index} within '
                    f'{self.lockstep_timeout_s} s; stepping without one'
                ),
            )
            self._advance(self.gate.hold(self.published_ns))

    def _now_ns(self) -> int:
        """Return the gate's clock.

        System time in real time, the published sample's stamp in sim.
        """
        return self.published_ns if self.mode == 'sim' else time.time_ns()

    def _sampling_loop(self) -> None:
        """Realtime: sleep until the next instant of the sample grid, sample, repeat.

        As ros2_control's loop does. One thread wake per sample, against two for an rclpy timer
        (its timer thread, then the executor); it inherits the process's SCHED_FIFO priority. An
        exception ends the run with the error (run_node exits 1) instead of leaving a node that no
        longer samples.
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
        """Integrate every whole period elapsed since the last sample, then publish the newest.

        After a stall the samples it covered are integrated one by one, each with what the gate
        says at its start (a 40 ms stall holds the current for the 10 ms timeout, then 0 A and
        the brake, as a drive's watchdog would), and only the newest is published.
        """
        due = (time.time_ns() - self.start_ns) // self.period_ns
        if due < self.next_sample:
            return
        while self.plant.sample_index < due:
            self.held = self.gate.hold(self.start_ns + self.plant.sample_index * self.period_ns)
            if self.held.reason == 'command timeout':
                self.log.warn('command_timeout', lambda: 'commands stopped: 0 A, brake engaged')
            self.plant.step(self.held.current_a, self.held.brake)
        self.next_sample = due + 1
        self._publish_sample()

    def _advance(self, held) -> None:
        """sim: integrate one sample with what the gate holds and publish the next."""
        self.held = held
        self.plant.step(held.current_a, held.brake)
        self._publish_sample()

    def _publish_sample(self) -> None:
        """Publish /clock (sim), the measurement and the ground truth of the current sample."""
        if (
            self.stop_after_s
            and self.plant.sample_index * self.period_ns >= self.stop_after_s * 1e9
        ):
            if not self.finished:
                self.get_logger().info(f'run of {self.stop_after_s} s complete')
            self.finished = True
            self.waiting_since_ns = None
            return
        stamp_ns = self.start_ns + self.plant.sample_index * self.period_ns
        stamp = ns_to_stamp(stamp_ns)
        if self.clock_pub is not None:
            self.clock_pub.publish(ClockMsg(clock=stamp))
            self.waiting_since_ns = self.wall.now().nanoseconds
        self.published_ns = stamp_ns
        self.joint_state.header.stamp = stamp
        self.joint_state.position[0] = float(self.plant.position_rad)
        self.state_pub.publish(self.joint_state)
        self.samples_log.append((stamp_ns, time.time_ns(), self.held.command_stamp_ns))
        self._publish_truth(stamp)

    def _publish_truth(self, stamp: Time) -> None:
        """Ground truth at t_k with the current held over the preceding sample."""
        current = self.held.current_a
        parts = self.plant.truth(current)
        f, m = parts.forces, self.truth
        m.header.stamp = stamp
        m.position_rad = float(self.plant.position_rad)
        m.velocity_rad_s = float(self.plant.velocity_rad_s)
        m.acceleration_rad_s2 = float(parts.acceleration_rad_s2)
        m.current_a = float(current)
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
        m.brake_engaged = bool(self.held.brake)
        self.truth_pub.publish(m)

    # --- commands --------------------------------------------------------------------------------
    def on_command(self, msg: CurrentCommand) -> None:
        """Stamp check, then the gate; sim: step when the command answers the waiting sample."""
        if not self.active or self.start_ns is None:
            return
        stamp_ns = stamp_to_ns(msg.header.stamp)
        if stamp_ns > self.published_ns and not msg.safe_stop:  # a safe stop is taken at any stamp
            self.log.error(
                'future_command',
                lambda: (
                    f'command stamped {stamp_ns} ns refused: it answers no sample '
                    f'taken yet (newest {self.published_ns} ns)'
                ),
            )
            return
        if self.conflict:
            self.log.error(
                'conflict', lambda: 'command refused: more than one publisher on current_command'
            )
            return
        refusal = self.gate.offer(msg.current_a, stamp_ns, msg.safe_stop, self._now_ns())
        if refusal:
            self.log.error('bad_command', lambda: refusal)
        if (
            self.mode == 'sim'
            and stamp_ns == self.published_ns
            and self.waiting_since_ns is not None
        ):
            self.waiting_since_ns = None
            self._advance(self.gate.hold(self.published_ns))

    def close_log(self) -> None:
        """Log a one-line summary; write the per-sample log if asked."""
        if self.timing_log:
            self.samples_log.save(self.timing_log)
        self.get_logger().info(
            f'stopped at sample {self.plant.sample_index} (t = {self.plant.time_s:.3f} s); '
            f'refused commands {self.gate.refused}, command timeouts {self.gate.timeouts}, '
            f'lockstep timeouts {self.lockstep_timeouts}'
        )


def main(argv=None) -> int:
    """Entry point of ``ros2 run actuator_plant plant_node``."""
    return run_node(
        'plant_node',
        'Simulated deep-sea oil-filled joint (sensor: angle only).',
        PlantNode,
        NODE_NAME,
        argv,
    )


if __name__ == '__main__':
    raise SystemExit(main())
