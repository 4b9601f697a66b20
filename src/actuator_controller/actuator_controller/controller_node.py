"""Joint controller node: PP-NFTSMC-ESO (or PI, SMC-ESO, NFTSMC-ESO) at the sensor's 1 kHz.

subscribes joint_states (sensor_msgs/JointState), eso/estimate (actuator_msgs/StateEstimate)
publishes  current_command (actuator_msgs/CurrentCommand), controller/state (actuator_msgs/ControllerState)

The control update of sample k runs as soon as y(k) and x_hat(k) (same stamp) are both in,
as ros2_control's update follows its read: the loop is clocked by the sensor's 1 kHz
sampling, and the sensor-to-command latency is one message hop plus the update. A timer on
the node clock (the ROS clock: wall time, or /clock in sim mode) at half the staleness
timeout is the watchdog:
when the newest measurement or estimate is older than its timeout, the node commands 0 A
with safe_stop set and says why. Invalid inputs (NaN, Inf, out of range) are refused and
answered with 0 A for that sample; a non-finite control output or an error beyond
following_error_limit_rad latches a safe stop until restart.

Timing is measured, not assumed: update period, sensor-to-command latency (wall clock minus
measurement stamp, realtime mode), compute time, late and missed samples. A summary is
logged at shutdown, and ``timing_log`` saves the raw samples (.npz).
"""

from __future__ import annotations

import math
import time

import numpy as np
from rclpy.node import Node

from actuator_core import limits
from actuator_ros.runtime import RateLimitedLog, MODES, ParameterError, control_qos, declare_choice, declare_number, \
    declare_spec_parameters, joint_position, ns_to_stamp, run_node
from actuator_core.sample_log import SampleLog
from actuator_core.timing import period_ns, sample_time_s, stamp_to_ns
from actuator_controller.laws import CONTROLLER_NAMES, GAINS_BY_NAME, CommonConfig, ControlOutput, make_controller
from actuator_controller.reference import make_reference
from actuator_msgs.msg import ControllerState, CurrentCommand, StateEstimate
from sensor_msgs.msg import JointState

#: Estimates kept while waiting for their measurement.
PENDING_LIMIT = 64




class ControllerNode(Node):
    """Runs one of the four control laws on the sensor/estimate streams."""

    def __init__(self) -> None:
        """Declare and check parameters, build the control law and the reference."""
        super().__init__('actuator_controller')
        self.log = RateLimitedLog(self.get_logger())
        self.mode = declare_choice(self, 'mode', 'realtime', MODES, 'realtime: wall clock; sim: /clock lockstep')
        name = declare_choice(self, 'controller', 'pp_nftsmc_eso', CONTROLLER_NAMES, 'control law')
        gains = declare_spec_parameters(self, GAINS_BY_NAME[name], prefix=f'{name}.')
        common = declare_spec_parameters(self, CommonConfig, prefix='common.')
        kind = declare_choice(self, 'reference', 'fast', ('slow', 'fast', 'step', 'sine'), 'reference trajectory')
        amplitude = declare_number(self, 'reference_amplitude_rad', 0.1, -10.0, 10.0, 'rad', 'step/sine amplitude')
        frequency = declare_number(self, 'reference_frequency_rad_s', 2.0 * math.pi, 0.0, 1.0e3, 'rad/s',
                                   'sine angular frequency')
        self.measurement_timeout_ns = int(1e9 * declare_number(
            self, 'measurement_timeout_s', limits.MEASUREMENT_TIMEOUT_S, *limits.TIMEOUT_RANGE_S, 's', 'older measurement: safe stop (0 A)'))
        self.estimate_timeout_ns = int(1e9 * declare_number(
            self, 'estimate_timeout_s', limits.ESTIMATE_TIMEOUT_S, *limits.TIMEOUT_RANGE_S, 's', 'older estimate: safe stop (0 A)'))
        self.following_error_limit_rad = declare_number(
            self, 'following_error_limit_rad', limits.FOLLOWING_ERROR_LIMIT_RAD, 1.0e-4, 100.0, 'rad', '|e| beyond latches a safe stop')
        self.max_abs_position_rad = declare_number(self, 'max_abs_position_rad', limits.POSITION_LIMIT_RAD, 0.0, 1.0e4, 'rad',
                                                   'measurements beyond are refused')
        self.joint_name = self.declare_parameter('joint_name', 'joint').value
        self.timing_log = self.declare_parameter('timing_log', '').value
        if self.mode == 'sim' and not self.get_parameter('use_sim_time').value:
            raise ParameterError("parameter 'use_sim_time' must be true in sim mode (the plant owns /clock)")
        self.law = make_controller(name, gains, common)
        self.needs_estimate = name != 'pi'
        self.reference = make_reference(kind, amplitude, frequency)
        self.period_ns = period_ns(common.dt_s)
        qos = control_qos(self.mode)
        self.cmd_pub = self.create_publisher(CurrentCommand, 'current_command', qos)
        self.state_pub = self.create_publisher(ControllerState, 'controller/state', qos)
        self.create_subscription(JointState, 'joint_states', self.on_measurement, qos)
        self.create_subscription(StateEstimate, 'eso/estimate', self.on_estimate, qos)
        # Half the shortest timeout is enough to notice staleness in time; a 1 kHz watchdog would
        # add a Python callback to every sample for nothing.
        self.watchdog = self.create_timer(min(self.measurement_timeout_ns, self.estimate_timeout_ns) * 0.5e-9,
                                          self.on_watchdog)
        # x_hat(k) by stamp: (x2_hat, x3_hat, input stamp, input current, input current gain).
        self.estimates: dict[int, tuple[float, float, int, float, float]] = {}
        self.commanded: tuple[int, float] = (-1, 0.0)   # (stamp, current) of the newest command
        self.corrected_estimates = 0
        self.envelope_restarts = 0
        self.newest_estimate_ns = None
        self.pending = None              # (stamp_ns, y) waiting for its estimate
        self.start_ns = None             # stamp of the first controlled sample (reference t = 0)
        self.last_measurement_ns = None
        self.latched = None              # status code of a latched safe stop
        self.status = ControllerState.STATUS_WAITING
        self.late = 0
        self.missed = 0
        self.stale_events = 0
        self.refused = 0
        self.unanswered = 0              # samples dropped while waiting for their estimate
        self.measurements_in = 0
        self.estimates_in = 0
        self.cmd = CurrentCommand()
        self.state = ControllerState(controller_name=name)
        self.timing = SampleLog(('received_wall_ns', 'stamp_ns', 'latency_ns', 'compute_ns'))
        self.get_logger().info(f'{name} on the {kind} reference, {self.mode} mode, current limit '
                               f'{common.current_limit_a} A')

    # --- inputs ---------------------------------------------------------------------------
    def on_measurement(self, msg: JointState) -> None:
        """y(k): check it, then control sample k as soon as x_hat(k) is in."""
        received_ns = time.time_ns()
        self.measurements_in += 1
        stamp = stamp_to_ns(msg.header.stamp)
        if self.last_measurement_ns is not None and stamp <= self.last_measurement_ns:
            return
        if self.last_measurement_ns is not None and stamp - self.last_measurement_ns > self.period_ns * 3 // 2:
            self.missed += (stamp - self.last_measurement_ns) // self.period_ns - 1
        self.last_measurement_ns = stamp
        y = joint_position(msg, self.joint_name)
        if y is None or not math.isfinite(y) or abs(y) > self.max_abs_position_rad:
            self.refused += 1
            self.log.error('bad_measurement', lambda: f'measurement refused (joint {self.joint_name!r} missing, non-finite or beyond '
                                    f'{self.max_abs_position_rad} rad): {list(msg.position)}; 0 A')
            self._safe_command(stamp, ControllerState.STATUS_INVALID_INPUT)
            return
        if self.pending is not None:
            self.unanswered += 1         # the previous sample's estimate never came in time
        self.pending = (stamp, y, received_ns)
        self._try_control()

    def on_estimate(self, msg: StateEstimate) -> None:
        """x_hat(k): check it and keep it until its measurement is in."""
        x2, x3 = msg.velocity_rad_s, msg.disturbance_rad_s2
        self.estimates_in += 1
        stamp = stamp_to_ns(msg.header.stamp)
        if not (math.isfinite(x2) and math.isfinite(x3)):
            self.refused += 1
            self.log.error('bad_estimate', lambda: f'estimate refused (non-finite: {x2}, {x3})')
            return
        self.estimates[stamp] = (x2, x3, stamp_to_ns(msg.input_stamp), msg.input_current_a, msg.input_current_gain)
        self.newest_estimate_ns = stamp if self.newest_estimate_ns is None else max(self.newest_estimate_ns, stamp)
        while len(self.estimates) > PENDING_LIMIT:
            self.estimates.pop(min(self.estimates))
        self._try_control()

    # --- control --------------------------------------------------------------------------
    def _try_control(self) -> None:
        """Control the pending sample when its estimate is in (PI needs none)."""
        if self.pending is None:
            return
        stamp, y, received_ns = self.pending
        if self.needs_estimate:
            entry = self.estimates.pop(stamp, None)
            if entry is None:
                return
            for old in [s for s in self.estimates if s < stamp]:
                del self.estimates[old]
            estimate = self._exact_estimate(*entry)
        else:
            estimate = (0.0, 0.0)
        self.pending = None
        self._control(stamp, y, estimate, received_ns)

    def _exact_estimate(self, x2: float, x3: float, input_ns: int, input_current: float,
                        gain: float) -> tuple[float, float]:
        """x_hat(k) as if the ESO had integrated the current this node commanded for sample k-1.

        When that command reached the observer too late, it stepped with a substitute; (15) is
        linear, so the exact estimate is x2_hat + (commanded - substitute) * input_current_gain
        (x1_hat and x3_hat do not depend on u(k-1) after one Euler step).
        """
        stamp, current = self.commanded
        if input_ns == stamp and current != input_current:
            self.corrected_estimates += 1
            return x2 + (current - input_current) * gain, x3
        return x2, x3

    def _control(self, stamp: int, y: float, estimate: tuple[float, float], received_ns: int) -> None:
        """Run the control law for sample ``stamp`` and publish the command and the state."""
        start = time.perf_counter_ns()
        if self.latched is not None:
            self._safe_command(stamp, self.latched)
            return
        if self.start_ns is None:
            self.start_ns = stamp
        t = sample_time_s(stamp - self.start_ns)
        ref = self.reference.sample(t)
        out = self.law.update(t, y, estimate[0], estimate[1], ref)
        if getattr(self.law, 'envelope_restarts', 0) != self.envelope_restarts:
            self.envelope_restarts = self.law.envelope_restarts
            self.log.warn('envelope', lambda: f'error {float(out.error_rad):.3g} rad left the prescribed envelope: '
                                              f'restarted it with rho0 = {float(out.rho_rad):.3g} rad '
                                              f'(restart {self.envelope_restarts})')
        status = ControllerState.STATUS_OK
        if not bool(out.finite):
            status = self.latched = ControllerState.STATUS_DIVERGED
            self.get_logger().error('control output not finite: safe stop latched (0 A) until restart')
        elif abs(float(out.error_rad)) > self.following_error_limit_rad:
            status = self.latched = ControllerState.STATUS_DIVERGED
            self.get_logger().error(f'|error| {abs(float(out.error_rad)):.3f} rad beyond following_error_limit_rad '
                                    f'{self.following_error_limit_rad}: safe stop latched (0 A) until restart')
        current = float(out.current_a) if status == ControllerState.STATUS_OK else 0.0
        self._publish_command(stamp, current, status != ControllerState.STATUS_OK)
        compute_ns = time.perf_counter_ns() - start
        wall_ns = time.time_ns()
        latency_ns = wall_ns - stamp if self.mode == 'realtime' else 0
        if self.mode == 'realtime' and latency_ns > self.period_ns:
            self.late += 1
            self.log.warn('late', lambda: f'late sample: command {latency_ns / 1e3:.0f} us after its measurement '
                                          f'(late {self.late}, missed {self.missed})')
        self.timing.append((received_ns, stamp, latency_ns, compute_ns))
        self.status = status
        self._publish_state(stamp, y, estimate, ref, out, current, compute_ns)

    def _publish_command(self, stamp: int, current: float, safe_stop: bool) -> None:
        """current_command answering sample ``stamp``."""
        self.cmd.header.stamp = ns_to_stamp(stamp)
        self.cmd.current_a = current
        self.cmd.safe_stop = safe_stop
        self.cmd_pub.publish(self.cmd)
        self.commanded = (stamp, current)

    def _safe_command(self, stamp: int, status: int) -> None:
        """Command 0 A with safe_stop for sample ``stamp`` and report why."""
        self._publish_command(stamp, 0.0, True)
        self.status = status
        s = self.state
        s.header.stamp = ns_to_stamp(stamp)
        s.status = status
        s.current_a = 0.0
        s.current_unlimited_a = float('nan')
        s.late_samples, s.missed_samples = self.late, self.missed
        self.state_pub.publish(s)

    def _publish_state(self, stamp: int, y: float, estimate, ref, out: ControlOutput, current: float,
                       compute_ns: int) -> None:
        """controller/state for sample ``stamp``."""
        s = self.state
        s.header.stamp = ns_to_stamp(stamp)
        s.reference_position_rad = float(ref.position_rad)
        s.reference_velocity_rad_s = float(ref.velocity_rad_s)
        s.reference_acceleration_rad_s2 = float(ref.acceleration_rad_s2)
        s.measured_position_rad = float(y)
        s.estimated_velocity_rad_s, s.estimated_disturbance_rad_s2 = (float(v) for v in estimate)
        s.error_rad = float(out.error_rad)
        s.rho_rad = float(out.rho_rad)
        s.lower_bound_rad = float(out.lower_bound_rad)
        s.upper_bound_rad = float(out.upper_bound_rad)
        s.bounds_kept = bool(out.bounds_kept)
        s.z1 = float(out.z1)
        s.z2_rad_s = float(out.z2_rad_s)
        s.alpha_rad_s = float(out.alpha_rad_s)
        s.alpha_dot_rad_s2 = float(out.alpha_dot_rad_s2)
        s.sigma_rad_s = float(out.sigma_rad_s)
        s.u_eq_rad_s2 = float(out.u_eq_rad_s2)
        s.u_sw_rad_s2 = float(out.u_sw_rad_s2)
        s.u_b_rad_s2 = float(out.u_b_rad_s2)
        s.proportional_a = float(out.proportional_a)
        s.integral_a = float(out.integral_a)
        s.current_unlimited_a = float(out.current_unlimited_a)
        s.current_a = current
        s.saturated = bool(out.saturated)
        s.status = self.status
        s.compute_time_s = compute_ns * 1e-9
        s.late_samples, s.missed_samples = self.late, self.missed
        self.state_pub.publish(s)

    # --- watchdog -------------------------------------------------------------------------
    def on_watchdog(self) -> None:
        """Stale measurement or estimate: command 0 A and say so (throttled)."""
        if self.start_ns is None or self.latched is not None:
            return
        now = self.get_clock().now().nanoseconds
        if now - self.last_measurement_ns > self.measurement_timeout_ns:
            reason, status, age_ns = 'measurement', ControllerState.STATUS_STALE_MEASUREMENT, now - self.last_measurement_ns
        elif self.needs_estimate and now - self.newest_estimate_ns > self.estimate_timeout_ns:
            reason, status, age_ns = 'estimate', ControllerState.STATUS_STALE_ESTIMATE, now - self.newest_estimate_ns
        else:
            return
        if self.status != status:
            self.stale_events += 1
        self.log.warn('stale', lambda: f'stale {reason} ({age_ns / 1e6:.1f} ms old): commanding 0 A')
        self._safe_command(now, status)

    # --- shutdown -------------------------------------------------------------------------
    def timing_summary(self) -> dict:
        """Period, latency and compute-time percentiles of the control updates so far."""
        rows = self.timing.array()
        summary = {'updates': self.timing.rows, 'measurements_in': self.measurements_in,
                   'estimates_in': self.estimates_in, 'late': self.late, 'missed': self.missed,
                   'unanswered': self.unanswered, 'stale_events': self.stale_events, 'refused_inputs': self.refused,
                   'corrected_estimates': self.corrected_estimates, 'envelope_restarts': self.envelope_restarts}
        if len(rows) > 2:
            period = np.diff(rows[:, 0]) / 1e3
            summary.update({
                'period_us_mean': float(period.mean()), 'period_us_p50': float(np.percentile(period, 50)),
                'period_us_p99': float(np.percentile(period, 99)), 'period_us_max': float(period.max()),
                'compute_us_p50': float(np.percentile(rows[:, 3], 50) / 1e3),
                'compute_us_p99': float(np.percentile(rows[:, 3], 99) / 1e3)})
            if self.mode == 'realtime':
                summary.update({'latency_us_p50': float(np.percentile(rows[:, 2], 50) / 1e3),
                                'latency_us_p99': float(np.percentile(rows[:, 2], 99) / 1e3),
                                'latency_us_max': float(rows[:, 2].max() / 1e3)})
        return summary

    def close(self) -> None:
        """Log the timing summary; write the raw timing samples if asked."""
        summary = self.timing_summary()
        self.get_logger().info('timing ' + ' '.join(f'{k}={v:.1f}' if isinstance(v, float) else f'{k}={v}'
                                                    for k, v in summary.items()))
        if self.timing_log:
            self.timing.save(self.timing_log)



def main(argv=None) -> int:
    """Entry point of ``ros2 run actuator_controller controller_node``."""
    return run_node('controller_node', 'PP-NFTSMC-ESO joint controller (PI, SMC-ESO, NFTSMC-ESO by parameter).',
                    ControllerNode, argv)


if __name__ == '__main__':
    raise SystemExit(main())
