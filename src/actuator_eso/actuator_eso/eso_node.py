# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Extended state observer node (managed).

It pairs each measurement with the current commanded for it.

subscribes joint_states (sensor_msgs/JointState) and current_command (actuator_msgs/CurrentCommand)
publishes  eso/estimate (actuator_msgs/StateEstimate)

The node holds an ``ExtendedStateObserver`` and its ``ObserverInputPairing`` (actuator_core),
the same objects as the offline loop: the pairing steps the observer once per (y(k), u(k))
pair by stamp and says what it did (substituted, repaired, restarted); the node only checks
what comes in and publishes what comes out (docs/concepts/sample-protocol.md).

Inputs: values are checked before stamps (a refused value never moves a stream's newest
stamp); a measurement whose implied velocity no joint can make is refused
(``MeasurementPlausibility``); every stamp passes a ``StampCheck``: a measurement from the
future or beyond what a stamp can hold is refused; a command counts only for a measurement
received or the next sample (the pairing's binding); a
discontinuity (a restarted plant or driver, a new grid) restarts the observer from the new
measurement (x_hat = (y, 0, 0)) and the restarted estimate is flagged ``initial``, which tells
the controller to hold 0 A until the observer has converged. A command stamped
from the future (real time) is refused; one far ahead of the observer is ignored by the
pairing (bounded work). Values beyond the physical ranges of actuator_core.limits are refused.
While more than one node publishes on joint_states or current_command (seen when it matches,
``GraphGuard``), the observer does not step (the controller, without estimates, stops safely)
and says so; once one publisher is left it restarts from the next measurement, as after every
activation.
"""

from __future__ import annotations

import json

from sensor_msgs.msg import JointState

from actuator_core.assembly import gap_limit_samples
from actuator_core.binding import MeasurementPlausibility
from actuator_core.clock import Clock, StampClock
from actuator_core.health import HealthMonitor, Level, Snapshot
from actuator_core.pairing import (
    REALTIME_PATIENCE_SAMPLES,
    SIM_PATIENCE_SAMPLES,
    Estimate,
    ObserverInputPairing,
)
from actuator_core.timebase import StampCheck, Verdict
from actuator_core.timing import period_ns, stamp_to_ns
from actuator_core.values import command_problem, measurement_problem
from actuator_eso.observer import EsoGains, ExtendedStateObserver
from actuator_msgs.msg import CurrentCommand, StateEstimate
from actuator_ros.conversions import joint_position
from actuator_ros.diagnostics import NodeDiagnostics
from actuator_ros.guard import GraphGuard
from actuator_ros.lockstep_hold import create_held_publisher
from actuator_ros.node import ManagedNode
from actuator_ros.parameters import declare_output_path, declare_shared, declare_spec_parameters
from actuator_ros.qos import control_qos
from actuator_ros.runner import run_node
from actuator_ros.wire_io import codec, subscribe_views

NODE_NAME = 'actuator_eso'
#: Control inputs whose publishers are counted (one each, or the observer stops).
WATCHED_TOPICS = ('joint_states', 'current_command')


class EsoNode(ManagedNode):
    """The ESO (15)-(16) between the sensor and the controller."""

    def __init__(self, settings=None) -> None:
        """Declare and check every parameter; nothing is built before configure."""
        super().__init__(NODE_NAME, **({'settings': settings} if settings else {}))

    def load_parameters(self) -> None:
        """Declare (or read again at configure) and check every parameter."""
        self.mode = declare_shared(self, 'mode')
        self.gains = declare_spec_parameters(self, EsoGains)
        self.dt_s = declare_shared(self, 'sample_time_s')
        self.current_limit_a = declare_shared(self, 'current_limit_a')
        self.future_tolerance_s = declare_shared(self, 'future_stamp_tolerance_s')
        self.joint_name = declare_shared(self, 'joint_name')
        self.lockstep_subscribers = declare_shared(self, 'lockstep_subscribers')
        self.stats_log = declare_output_path(
            self, 'stats_log', 'pairing counts (.json) written at shutdown'
        )
        self.refuse_sim_time_in_realtime(self.mode)

    # --- lifecycle -------------------------------------------------------------------------------
    def build(self) -> None:
        """Observer, pairing, stamp checks and topics."""
        self.period_ns = period_ns(self.dt_s)
        self.observer = ExtendedStateObserver(self.gains, self.dt_s)
        patience = SIM_PATIENCE_SAMPLES if self.mode == 'sim' else REALTIME_PATIENCE_SAMPLES
        self.pairing = ObserverInputPairing(
            self.observer,
            self.period_ns,
            self.observer.correction,
            patience,
            None if self.mode == 'sim' else gap_limit_samples(self.period_ns),
        )
        self.measurement_check = StampCheck(
            self.period_ns, self.mode == 'sim', int(self.future_tolerance_s * 1e9)
        )
        self.input_current_gain = self.dt_s * self.gains.theta1n
        self.clock = Clock()
        self.stamp_clock = StampClock(self.clock)  # stamp time, which a wall-clock step leaves
        self.plausibility = MeasurementPlausibility()
        self.refused = 0
        self.refusals: dict[str, int] = {}  # by reason, for /diagnostics
        self.conflict = ''
        self.restart_next = False
        self.guard = GraphGuard(self, self.on_conflict)
        qos = control_qos(self.mode)
        # sim: estimates are held until the controller's (and the recorder's) readers matched
        # (a lost x_hat(0) left the lockstep waiting for good at start-up)
        self.pub, self.hold = create_held_publisher(
            self,
            StateEstimate,
            'eso/estimate',
            qos,
            self.lockstep_subscribers if self.mode == 'sim' else 0,
        )
        self.subs = [
            subscribe_views(
                self, kind, topic, callback, qos, event_callbacks=self.guard.callbacks(topic)
            )
            for kind, topic, callback in (
                (JointState, 'joint_states', self.on_measurement),
                (CurrentCommand, 'current_command', self.on_command),
            )
        ]
        self.encode_estimate = codec(StateEstimate).encode
        self.diagnostics = NodeDiagnostics(self, self.health_monitor(), self.health)
        beta = ', '.join(f'{b:.4g}' for b in self.gains.beta)
        self.get_logger().info(
            f'{self.mode} mode, w0 = {self.gains.omega0_rad_s} rad/s, beta = ({beta}), '
            f'dt = {self.dt_s} s'
        )

    def start(self) -> None:
        """(Re)activation: the observer restarts from the next measurement (no back-fill)."""
        self.restart_next = True

    def stop(self) -> None:
        """Stop stepping; log and write the counts."""
        self.close_log()

    def drop(self) -> None:
        """Destroy the topics and the diagnostics."""
        self.diagnostics.destroy()
        for sub in self.subs:
            self.destroy_subscription(sub)
        self.destroy_lifecycle_publisher(self.pub)

    def health_monitor(self) -> HealthMonitor:
        """Rules of /diagnostics: STALE without paired samples; WARN on refusals, substitutions."""
        return HealthMonitor(
            NODE_NAME,
            inputs={'steps': 'paired samples (joint_states with current_command)'},
            warn_on={
                'refused *': 'refused inputs',
                'substituted_pairs': 'substituted commands',
                'restarts': 'observer restarts',
            },
        )

    def health(self) -> Snapshot:
        """Report to /diagnostics: counts, mode, a publisher conflict."""
        p = self.pairing
        return Snapshot(
            'active' if self.active else 'inactive',
            {
                'steps': p.steps,
                'substituted_pairs': p.substituted,
                'repaired_pairs': p.repaired,
                'restarts': p.restarts,
                'refused_inputs': self.refused,
                'ignored_inputs': p.ignored + self.measurement_check.ignored_old,
                **{f'refused {k}': n for k, n in self.refusals.items()},
            },
            {'mode': self.mode, 'omega0_rad_s': self.gains.omega0_rad_s},
            [(Level.ERROR, f'{self.conflict}: not estimating')] if self.conflict else [],
        )

    # --- inputs ----------------------------------------------------------------------------------
    def on_conflict(self, conflict: str) -> None:
        """Handle a change of the matched publishers: more than one stops the observer."""
        if conflict != self.conflict:
            if conflict:
                self.get_logger().error(f'{conflict}: not estimating until one publisher is left')
            else:
                self.get_logger().warning(
                    'one publisher per control input again: the observer restarts from the '
                    'next measurement'
                )
                self.restart_next = True
            self.conflict = conflict

    def _refuse(self, key: str, why) -> None:
        """Count and log (rate-limited) a refused input."""
        self.refused += 1
        self.refusals[key] = self.refusals.get(key, 0) + 1
        self.log.error(key, why)

    def on_measurement(self, msg: JointState) -> None:
        """y(k): stamp and value checked, then the pairing; publish what it produced."""
        if not self.active:
            return
        y = joint_position(msg, self.joint_name)
        problem = measurement_problem(y, self.joint_name, msg.position)
        if problem or y is None:  # (no angle is a problem)
            self._refuse('bad_measurement', lambda: problem)
            return
        stamp = stamp_to_ns(msg.header.stamp)
        if self.conflict:
            return
        implausible = self.plausibility.check(stamp, y)
        rebased = bool(implausible) and self.plausibility.refuse(stamp, y)
        if implausible and not rebased:
            self._refuse('implausible', lambda: implausible)
            return
        received_ns = self.clock.now_ns()
        verdict = self.measurement_check.check(stamp, self.stamp_clock.at(received_ns))
        if verdict is Verdict.JUMP:  # a new time base: stamp time follows it from here
            self.stamp_clock.adopt(stamp, received_ns)
        if verdict in (Verdict.FUTURE, Verdict.INVALID):
            self._refuse(
                verdict.value,
                lambda: (
                    f'measurement stamped {stamp} ns refused: '
                    + ('beyond the sample clock' if verdict is Verdict.FUTURE else 'not a stamp')
                ),
            )
        elif verdict is Verdict.JUMP or (verdict is Verdict.OK and (self.restart_next or rebased)):
            why = (
                'a jump of the time base: a restarted sensor?'
                if verdict is Verdict.JUMP
                else 'a step of the measurement that persisted'
                if rebased
                else 'activation, or the end of a publisher conflict'
            )
            self.restart_next = False
            self.plausibility.rebase(stamp, y)
            self.get_logger().warning(
                f'observer restarted from the measurement at {stamp} ns ({why})'
            )
            for estimate in self.pairing.restart(stamp, y):
                self._publish(estimate)
        elif verdict is Verdict.OK:
            self.plausibility.accept(stamp, y)
            restarts = self.pairing.gap_restarts
            estimates = self.pairing.add_measurement(stamp, y)
            if self.pairing.gap_restarts != restarts:
                self.get_logger().warning(
                    f'observer restarted from the measurement at {stamp} ns: no measurement '
                    'paired for longer than the command timeout (a stall?); no back-fill'
                )
            for estimate in estimates:
                self._publish(estimate)

    def on_command(self, msg: CurrentCommand) -> None:
        """u(k): not from the future, finite and within the current limit; then the pairing."""
        if not self.active:
            return
        u = msg.current_a
        problem = command_problem(u, self.current_limit_a)
        if problem:
            self._refuse('bad_command', lambda: problem)
            return
        stamp = stamp_to_ns(msg.header.stamp)
        if self.conflict:
            return
        for estimate in self.pairing.add_command(stamp, u):
            self._publish(estimate)
        why = self.pairing.refusal
        if why:
            self._refuse(
                'command_binding' if 'refused' in why else 'command_conflict', lambda: why
            )

    def _publish(self, e: Estimate) -> None:
        """Publish x_hat for ``e.sample_ns``; log a substitution (rate-limited)."""
        if e.substituted:
            self.log.warn(
                'substituted',
                lambda: (
                    f'sample {e.input_ns} ns: command missing; integrating with the last current'
                ),
            )
        x1, x2, x3 = e.x_hat
        self.hold.publish(
            self.encode_estimate(
                {
                    'header.stamp': e.sample_ns,
                    'header.frame_id': '',
                    'position_rad': float(x1),
                    'velocity_rad_s': float(x2),
                    'disturbance_rad_s2': float(x3),
                    'input_stamp': e.input_ns,
                    'input_position_rad': float(e.input_position_rad),
                    'input_current_a': float(e.input_current_a),
                    'input_current_gain': self.input_current_gain,
                    'initial': bool(e.initial),
                    'current_substituted': bool(e.substituted),
                    'missing_current_count': self.pairing.substituted,
                }
            )
        )

    def close_log(self) -> None:
        """Log a one-line summary; write the pairing counts as JSON if asked."""
        p = self.pairing
        self.get_logger().info(
            f'stopped; steps {p.steps}, substituted pairs {p.substituted} (repaired when the '
            f'command came late: {p.repaired}), restarts {p.restarts}, refused inputs '
            f'{self.refused}, ignored {p.ignored + self.measurement_check.ignored_old}'
        )
        if self.stats_log:
            with open(self.stats_log, 'w') as f:
                json.dump(
                    {
                        'steps': p.steps,
                        'exact_pairs': p.steps - p.substituted,
                        'substituted_pairs': p.substituted,
                        'repaired_pairs': p.repaired,
                        'restarts': p.restarts,
                        'refused_inputs': self.refused,
                    },
                    f,
                )


def main(argv=None) -> int:
    """Entry point of ``ros2 run actuator_eso eso_node``."""
    return run_node(
        'eso_node', 'Extended state observer (15)-(16) of the joint.', EsoNode, NODE_NAME, argv
    )


if __name__ == '__main__':
    raise SystemExit(main())
