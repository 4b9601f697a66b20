# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Managed (lifecycle) CiA 402 driver node: drops in for the simulated plant, speaking CANopen.

Topic contract (identical to actuator_plant's plant_node, docs/architecture.md):
  publishes  joint_states (sensor_msgs/JointState: name = [joint_name], position only;
             header.stamp = the SYNC instant t_k on the sample grid), once per cycle
  subscribes current_command (actuator_msgs/CurrentCommand), through a CommandGate into the
             RPDO target torque 0x6071 of each SYNC
  publishes  diagnostics (diagnostic_msgs/DiagnosticArray): lifecycle and drive state, error code

Lifecycle: configure = bus up (and the simulated drive), OD checks, PDO mapping, CST mode, no
publishing; activate = fault reset if needed, enable sequence, NMT operational, cycle starts;
deactivate = cycle stops, quick stop, disable voltage (brake); a drive fault (statusword fault
bit or EMCY) or a silent bus ends the cycle at once (0 A, brake, no more joint_states: the
controller safe-stops on stale measurements) and takes the node through error processing,
which logs the drive's error code and text, to unconfigured.
"""

from __future__ import annotations

import faulthandler
import os
import signal
import threading
import time
from typing import Optional

import can
import canopen
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from sensor_msgs.msg import JointState

from actuator_core.gate import CommandGate
from actuator_core.sample_log import SampleLog
from actuator_core.timing import stamp_to_ns
from actuator_msgs.msg import CurrentCommand
from actuator_ros.conversions import ns_to_stamp
from actuator_ros.log import RateLimitedLog
from actuator_ros.node import declare_realtime
from actuator_ros.parameters import (
    ParameterError,
    check_unknown_parameters,
    declare_flag,
    declare_spec_parameters,
)
from actuator_ros.realtime import RealtimeSettings
from actuator_ros.qos import control_qos
from actuator_ros.runner import run_node
from actuator_cia402 import profile as p
from actuator_cia402.busload import check_bus_load, cycle_load
from actuator_cia402.config import DriverParameters
from actuator_cia402.cycle import SyncCycle
from actuator_cia402.master import Cia402Error, Cia402Master, DriveFault, Feedback
from actuator_cia402.sim_drive import SimulatedDrive, plant_parameters

NODE_NAME = 'actuator_cia402_driver'
#: Longest idle wait of a bus thread [s]: how long stopping it can take (canopen's default is 1 s).
NOTIFIER_CYCLE_S = 0.1


class Cia402DriverNode(LifecycleNode):
    """The hardware driver behind the joint_states / current_command contract."""

    def __init__(self, settings: Optional[RealtimeSettings] = None, **node_kwargs) -> None:
        """Declare and check every parameter (a refusal exits 2); create topics.

        Nothing on the bus yet.
        """
        super().__init__(NODE_NAME, **node_kwargs)
        if self.get_parameter('use_sim_time').value:
            raise ParameterError(
                "parameter 'use_sim_time' must be false for the driver: the drive's SYNC "
                'grid runs on the system clock'
            )
        self.cfg: DriverParameters = declare_spec_parameters(
            self, DriverParameters, read_only=True
        )
        declare_flag(
            self,
            'allow_unknown_parameters',
            False,
            'accept names this node does not declare, with a '
            'warning (a /** section shared by several nodes)',
        )
        self.settings = declare_realtime(self, settings or RealtimeSettings())
        self.log = RateLimitedLog(self.get_logger())
        self.scaling = self.cfg.scaling
        self.eds = self.cfg.eds_path()
        if not os.path.isfile(self.eds):
            raise ParameterError(
                f"parameter 'eds_file' = {self.eds!r} refused: no such file (the drive's EDS)"
            )
        self.bus_load = cycle_load(self.cfg.bitrate, self.cfg.sync_period_s)
        self.gate = CommandGate(self.cfg.current_limit_a, self.cfg.command_timeout_s)
        # offer (executor thread) and hold (cycle thread) never interleave:
        # one command's current with another's stamp.
        self.gate_lock = threading.Lock()
        self.brake_delay_ns = int(round(self.cfg.brake_delay_s * 1e9))
        self._brake_since_ns: Optional[int] = None
        self.brake_commanded = True
        # Per published sample, as the plant node logs it: stamp, wall time of publication, stamp
        # of the command held over the preceding SYNC interval (-1: none).
        self.samples_log = SampleLog(('stamp_ns', 'published_wall_ns', 'held_command_stamp_ns'))
        self._held_stamps = [-1, -1]  # command stamps written in the previous and this cycle
        qos = control_qos('realtime')
        self.state_pub = self.create_publisher(JointState, 'joint_states', qos)
        self.diag_pub = self.create_publisher(DiagnosticArray, 'diagnostics', 10)
        self.create_subscription(CurrentCommand, 'current_command', self.on_command, qos)
        self.joint_state = JointState(name=[self.cfg.joint_name], position=[0.0])
        self.network: Optional[canopen.Network] = None
        self.drive: Optional[SimulatedDrive] = None
        self.master: Optional[Cia402Master] = None
        self.cycle: Optional[SyncCycle] = None
        self.last_feedback: Optional[Feedback] = None
        self.last_fault: Optional[DriveFault] = None
        self.finished = False  # read by run_node
        self.error: Optional[str] = None  # read by run_node
        self.refused = 0
        self._warned = 0
        self._autostart_stage = 'configure' if self.cfg.autostart else None
        self._settle_until_ns: Optional[int] = None
        self._next_diag_ns = 0
        self.wall = Clock(clock_type=ClockType.STEADY_TIME)
        # (The conditional part is computed first only because it is longer than a line.)
        simulated = (
            ', simulated drive (' + self.cfg.sim.working_condition + ')'
            if self.cfg.simulated_drive
            else ''
        )
        self.get_logger().info(
            f'node {self.cfg.node_id} on {self.cfg.interface}:{self.cfg.channel} at '
            f'{self.cfg.bitrate / 1000:g} kbit/s, '
            f'SYNC {1.0 / self.cfg.sync_period_s:g} Hz, bus load {self.bus_load.text()}'
            f'{simulated}'
        )
        note = check_bus_load(
            self.cfg.bitrate, self.cfg.sync_period_s, limit=self.cfg.bus_load_limit
        )
        if note:
            self.get_logger().warning(note)
        self.create_timer(0.02, self.on_supervise, clock=self.wall)
        unknown = check_unknown_parameters(self)
        if unknown:
            self.get_logger().warning(
                f'ignoring parameters this node does not have: {", ".join(unknown)}'
            )

    # --- lifecycle --------------------------------------------------------------------------
    @property
    def lifecycle_state(self) -> str:
        """Label of the present lifecycle state ('unconfigured', 'inactive', 'active', ...)."""
        return self._state_machine.current_state[1]

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Bus up (+ simulated drive), OD checks, PDO mapping, CST.

        FAILURE with the reason otherwise.
        """
        cfg = self.cfg
        try:
            if (
                cfg.simulated_drive and self.drive is None
            ):  # the drive outlives configure/cleanup, as hardware does
                self.drive = SimulatedDrive(
                    self.eds,
                    cfg.node_id,
                    self.scaling,
                    cfg.sync_period_s,
                    cfg.channel,
                    'virtual',
                    plant_parameters(cfg.sim.working_condition),
                    cfg.sim.torque_time_constant_s,
                    cfg.sim.fault_plan(),
                    cfg.current_limit_a,
                    cfg.command_timeout_s,
                    cfg.sim.over_current_a,
                    cfg.sim.initial_position_rad,
                ).start()
            self.network = canopen.Network()
            self.network.NOTIFIER_CYCLE = NOTIFIER_CYCLE_S
            kwargs = (
                {'receive_own_messages': False}
                if cfg.interface == 'virtual'
                else {'bitrate': cfg.bitrate}
            )
            try:
                self.network.connect(interface=cfg.interface, channel=cfg.channel, **kwargs)
            except (OSError, can.CanError) as exc:
                raise Cia402Error(
                    f'cannot open {cfg.interface} channel {cfg.channel!r} ({exc}); is the '
                    'interface up? '
                    f'ip link set {cfg.channel} up type can bitrate {cfg.bitrate}'
                ) from None
            self.master = Cia402Master(
                self.network,
                cfg.node_id,
                self.eds,
                self.scaling,
                cfg.sync_period_s,
                *cfg.cob_ids,
                cfg.current_limit_a,
                cfg.state_timeout_s,
                cfg.sdo_timeout_s,
            )
            for note in self.master.configure():
                self.get_logger().warning(note)
        except Exception as exc:  # noqa: BLE001 - any failure of the bus or drive is a failed configure, said in one line
            self.get_logger().error(f'configure failed: {exc}')
            self._bus_down()
            return TransitionCallbackReturn.FAILURE
        self.get_logger().info(
            f'configured: node {cfg.node_id} is a CiA 402 drive in CST, PDOs mapped '
            f'(RPDO 0x{cfg.cob_ids[0]:03X}, TPDO 0x{cfg.cob_ids[1]:03X}/0x{cfg.cob_ids[2]:03X})'
        )
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Enable sequence, NMT operational, gate open, cycle thread started."""
        try:
            for note in self.master.activate():
                self.get_logger().warning(note)
        except Exception as exc:  # noqa: BLE001 - any failure of the enable sequence is a failed activate
            self.get_logger().error(f'activate failed: {exc}')
            return TransitionCallbackReturn.FAILURE
        self.last_fault = None
        with self.gate_lock:
            self.gate.activate()
        cfg = self.cfg
        self.cycle = SyncCycle(
            self.master,
            cfg.sync_period_s,
            cfg.tpdo_wait_fraction * cfg.sync_period_s,
            cfg.feedback_timeout_s,
            self._command,
            self._publish_sample,
            cfg.stop_after_s,
        )
        self.cycle.start()
        self.get_logger().info('active: operation enabled, SYNC cycle started (sampling started)')
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop the cycle, 0 A, quick stop and disable (brake).

        ERROR when a drive fault ended the cycle.
        """
        fault = self._stop_cycle()
        if fault is not None:
            self.last_fault = fault
            return TransitionCallbackReturn.ERROR
        try:
            self.master.deactivate()
        except (Cia402Error, canopen.SdoAbortedError, canopen.SdoCommunicationError) as exc:
            self.get_logger().error(f'deactivate: {exc}')
            return TransitionCallbackReturn.ERROR
        self.get_logger().info('inactive: quick stop, voltage disabled, brake engaged')
        return super().on_deactivate(state)

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Error processing.

        Log the drive's error code and text, make the drive safe if it answers, bus down.
        """
        self._stop_cycle()
        fault = self.last_fault
        if (
            fault is not None
            and fault.code == 0
            and fault.source == 'statusword'
            and self.master is not None
        ):
            try:
                fault = self.last_fault = DriveFault(*self.master.read_error(), fault.source)
            except (canopen.SdoAbortedError, canopen.SdoCommunicationError):
                pass
        if fault is not None:
            self.get_logger().error(
                f'drive fault ({fault.source}): error code 0x{fault.code:04X} {fault.text}; '
                'measurements stopped, command at 0 A, brake engaged'
            )
        if self.master is not None and (fault is None or fault.source != 'feedback timeout'):
            try:
                self.master.deactivate()
            except (Cia402Error, canopen.SdoAbortedError, canopen.SdoCommunicationError) as exc:
                self.get_logger().warning(f'error processing: drive not made safe over SDO: {exc}')
        self._bus_down()
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Bus down."""
        self._bus_down()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop the cycle, make the drive safe, bus down."""
        self._safe_shutdown()
        return TransitionCallbackReturn.SUCCESS

    def _stop_cycle(self) -> Optional[DriveFault]:
        """Stop the cycle thread and close the gate; returns the fault that ended it, if any."""
        with self.gate_lock:
            self.gate.deactivate()
        if self.cycle is None:
            return None
        self.cycle.stop()
        fault = self.cycle.fault if self.cycle.ended in ('fault', 'error') else None
        self._last_stats = self.cycle.stats
        self.cycle = None
        return fault

    def _bus_down(self, drive_too: bool = False) -> None:
        """Disconnect the master's network.

        With ``drive_too`` also stop the simulated drive (node exit).
        """
        things = [self.network] + ([self.drive] if drive_too else [])
        for thing in things:
            if thing is not None:
                try:
                    (thing.disconnect if thing is self.network else thing.stop)()
                except Exception as exc:  # noqa: BLE001 - shutting down: report, go on
                    self.get_logger().warning(f'bus down: {exc!r}')
        self.network = self.master = None
        if drive_too:
            self.drive = None

    def _safe_shutdown(self) -> None:
        """Active or inactive: quick stop and disable if the drive answers.

        Then bus and simulated drive down.
        """
        fault = self._stop_cycle()
        if self.master is not None and fault is None:
            try:
                self.master.deactivate()
            except (Cia402Error, canopen.SdoAbortedError, canopen.SdoCommunicationError) as exc:
                self.get_logger().warning(f'shutdown: {exc}')
        self._bus_down(drive_too=True)

    # --- cycle callbacks (cycle thread) -----------------------------------------------------
    def _command(self, t_ns: int) -> tuple[int, float]:
        """Controlword and current of this SYNC.

        'disable operation' (brake) before a command or after brake_delay_s.
        """
        now = time.time_ns()
        with self.gate_lock:
            held = self.gate.hold(now)
        if not held.brake:
            self._brake_since_ns = None
        elif self._brake_since_ns is None:
            self._brake_since_ns = now
        engage = held.brake and (
            held.reason in ('no command yet', 'inactive')
            or now - self._brake_since_ns >= self.brake_delay_ns
        )
        self.brake_commanded = engage
        self._held_stamps = [self._held_stamps[1], held.command_stamp_ns]
        return (
            p.Command.SWITCH_ON if engage else p.Command.ENABLE_OPERATION
        ).value, held.current_a

    def _publish_sample(self, stamp_ns: int, feedback: Feedback) -> None:
        """joint_states stamped t_k (the SYNC instant) with the angle of TPDO1."""
        self.last_feedback = feedback
        self.joint_state.header.stamp = ns_to_stamp(stamp_ns)
        self.joint_state.position[0] = feedback.position_rad
        self.state_pub.publish(self.joint_state)
        self.samples_log.append((stamp_ns, time.time_ns(), self._held_stamps[0]))

    # --- commands ---------------------------------------------------------------------------
    def on_command(self, msg: CurrentCommand) -> None:
        """Offer a command to the gate (refused: logged, 0 A and brake)."""
        with self.gate_lock:
            reason = self.gate.offer(
                msg.current_a, stamp_to_ns(msg.header.stamp), msg.safe_stop, time.time_ns()
            )
        if reason is not None and self.gate.active:
            self.refused += 1
            self.log.error('bad_command', lambda: reason)

    # --- supervision (executor thread, 50 Hz) -----------------------------------------------
    def on_supervise(self) -> None:
        """Autostart, fault -> error processing, end of run, diagnostics."""
        if self._autostart_stage is not None:
            self._autostart()
        cycle = self.cycle
        if cycle is not None and cycle.ended is not None:
            if cycle.ended in ('fault', 'error'):
                self.get_logger().error(
                    f'cycle ended by a fault: {cycle.fault.text}; error processing'
                )
            self.trigger_deactivate()
            if self.cfg.stop_after_s and self.lifecycle_state == 'inactive':
                self.get_logger().info(f'run of {self.cfg.stop_after_s} s complete')
                self.finished = True
        if self.master is not None:
            for warning in self.master.warnings[self._warned :]:
                self.get_logger().warning(f'drive: {warning}')
            self._warned = len(self.master.warnings)
        now = self.wall.now().nanoseconds
        if now >= self._next_diag_ns:
            self._next_diag_ns = now + int(self.cfg.diagnostics_period_s * 1e9)
            self.diag_pub.publish(self.diagnostics())

    def _autostart(self) -> None:
        """Configure at once; activate when wait_for_subscribers have joined (and 0.5 s later)."""
        if self._autostart_stage == 'configure':
            if self.trigger_configure() != TransitionCallbackReturn.SUCCESS:
                self.error, self.finished, self._autostart_stage = (
                    'autostart: configure failed',
                    True,
                    None,
                )
                return
            self._autostart_stage = 'activate'
        n = self.cfg.wait_for_subscribers
        ready = self.state_pub.get_subscription_count() >= n and (
            n == 0 or self.count_publishers('current_command')
        )
        now = self.wall.now().nanoseconds
        if not ready:
            self._settle_until_ns = None
            return
        if self._settle_until_ns is None:
            self._settle_until_ns = now + (500_000_000 if n else 0)
        if now >= self._settle_until_ns:
            self._autostart_stage = None
            if self.trigger_activate() != TransitionCallbackReturn.SUCCESS:
                self.error, self.finished = 'autostart: activate failed', True

    def diagnostics(self) -> DiagnosticArray:
        """One DiagnosticStatus.

        Lifecycle and CiA 402 state, error code and text, cycle figures.
        """
        fb, fault, cycle = self.last_feedback, self.last_fault, self.cycle
        state = p.decode_state(fb.statusword) if fb is not None else None
        level = DiagnosticStatus.OK
        message = f'{self.lifecycle_state}; drive {state.value if state else "unknown"}'
        if fault is not None:
            level, message = (
                DiagnosticStatus.ERROR,
                f'{message}; fault 0x{fault.code:04X} {fault.text}',
            )
        elif self.lifecycle_state != 'active':
            level = DiagnosticStatus.WARN
        values = {
            'lifecycle_state': self.lifecycle_state,
            'drive_state': state.value if state else 'unknown',
            'statusword': f'0x{fb.statusword:04X}' if fb else '',
            'error_code': f'0x{fault.code:04X}'
            if fault
            else (f'0x{fb.error_code:04X}' if fb else ''),
            'error_text': fault.text if fault else '',
            'brake': str(self.brake_commanded or self.lifecycle_state != 'active'),
            'bus_load_percent': f'{100 * self.bus_load.fraction:.1f}',
            'refused_commands': str(self.refused),
            'command_timeouts': str(self.gate.timeouts),
        }
        if cycle is not None:
            stats = cycle.stats
            values.update(
                {
                    'cycles': str(stats.cycles),
                    'missed_tpdo': str(stats.missed_feedback),
                    'overruns': str(stats.overruns),
                }
            )
            values.update({k: f'{v:.1f}' for k, v in stats.medians_us().items()})
        if fb is not None:
            values.update(
                {
                    'torque_actual_nm': f'{fb.torque_nm:.4f}',
                    'current_actual_a': f'{fb.current_a:.3f}',
                }
            )
        status = DiagnosticStatus(
            level=level,
            name=f'{self.get_name()}: CiA 402 drive {self.cfg.node_id}',
            message=message,
            hardware_id=f'{self.cfg.interface}:{self.cfg.channel}/{self.cfg.node_id}',
            values=[KeyValue(key=k, value=v) for k, v in values.items()],
        )
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        return msg

    def close(self) -> None:
        """At exit (run_node).

        Stop the cycle, quick stop and disable the drive, bus down, summary.
        """
        stats = self.cycle.stats if self.cycle is not None else getattr(self, '_last_stats', None)
        self._safe_shutdown()
        if self.cfg.timing_log:
            self.samples_log.save(self.cfg.timing_log)
        if stats is not None:
            m = stats.medians_us()
            self.get_logger().info(
                f'stopped after {stats.cycles} cycles: missed TPDOs {stats.missed_feedback}, '
                f'overruns {stats.overruns}, CPU per cycle p50 {m["cpu_p50_us"]:.0f} us, '
                f'refused commands {self.refused}, command timeouts {self.gate.timeouts}'
            )


def main(argv=None) -> int:
    """Entry point of ``ros2 run actuator_cia402 cia402_driver``.

    ``kill -USR1 <pid>`` dumps every thread's stack.
    """
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    return run_node(
        'cia402_driver',
        'CiA 402 (CANopen) joint drive driver, lifecycle node.',
        lambda settings: Cia402DriverNode(settings),
        NODE_NAME,
        argv,
    )


if __name__ == '__main__':
    raise SystemExit(main())
