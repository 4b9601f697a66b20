# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The closed loop: the objects the three nodes hold, called in the order the nodes call them.

Sample k (see docs/concepts/architecture.md#sample-timing), each step the same call a node makes:
  1. the joint integrates [t_k-1, t_k) and samples y(k)   (joint node: ``SimulatedJoint``);
  2. the observer pairing takes y(k)                      (ESO node: ``ObserverInputPairing``);
  3. the controller assembly takes x_hat(k) and y(k) and
     runs the law for u(k)                 (controller node: ``ControlSampleAssembly``);
  4. the joint's gate takes u(k) with its safe_stop and holds it, brake included
                                          (joint node: ``CommandGate``), written to the joint;
  5. the pairing takes u(k): one observer step to x_hat(k+1).
  6. (reference ``hold``) the trajectory execution judges the running goal on sample k and
     takes the goals and cancels handed to it before k   (controller node: the same object).
The nodes hold these same classes (``actuator_core``), so a run in deterministic sim time
reproduces this loop sample by sample by construction, and a test checks it bit for bit
(``tests/test_closed_loop_nodes.py``). Stamps are integer nanoseconds from t_0 = 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from actuator_controller.commanded_reference import CommandedReference
from actuator_controller.goal_execution import Goal, GoalEvent, TrajectoryExecution
from actuator_controller.laws import (
    CommonConfig,
    ControlOutput,
    NftsmcGains,
    PiGains,
    SmcGains,
    make_controller,
)
from actuator_controller.reference import make_reference
from actuator_controller.trajectory import DesiredState
from actuator_controller.trajectory_settings import TrajectorySettings
from actuator_core.assembly import ControlSampleAssembly
from actuator_core.gate import CommandGate
from actuator_core.limits import DIVERGENCE_ERROR_RAD
from actuator_core.pairing import SIM_PATIENCE_SAMPLES, Estimate, ObserverInputPairing
from actuator_core.status import Status
from actuator_core.timing import period_ns, sample_time_s
from actuator_eso.observer import EsoGains, ExtendedStateObserver
from actuator_plant.encoder import Encoder, EncoderParameters
from actuator_plant.model import PlantParameters
from actuator_plant.sim_joint import SimulatedJoint

#: Per-sample quantities recorded besides the controller's own ControlOutput fields.
EXTRA_FIELDS = (
    't_s',
    'reference_position_rad',
    'reference_velocity_rad_s',
    'reference_acceleration_rad_s2',
    'measured_position_rad',
    'x1_hat_rad',
    'x2_hat_rad_s',
    'x3_hat_rad_s2',
    'true_velocity_rad_s',
    'true_disturbance_rad_s2',
)
TRACE_FIELDS = EXTRA_FIELDS + ControlOutput._fields + ('status',)
NAN = float('nan')


@dataclass
class Scenario:
    """A closed-loop run: plant, observer, controller, reference and duration."""

    name: str
    controller: str = 'pp_nftsmc_eso'
    reference: str = 'fast'
    plant: PlantParameters = field(default_factory=PlantParameters)
    eso: EsoGains = field(default_factory=EsoGains)
    #: the law's gains (PpNftsmcGains is an NftsmcGains); None: Table 4's
    gains: PiGains | SmcGains | NftsmcGains | None = None
    common: CommonConfig = field(default_factory=CommonConfig)
    duration_s: float = 10.0
    #: Encoder between the joint and the controller/ESO (None: the exact angle, as in the paper).
    encoder: EncoderParameters | None = None
    #: Samples between a command and its application by the plant (0: the paper's loop).
    command_delay_samples: int = 0
    #: First-order torque loop of a drive between command and joint [s] (0: none, the paper's).
    torque_time_constant_s: float = 0.0
    #: What goals are judged by (reference ``hold``): JTC's tolerances and the soft limits.
    trajectory: TrajectorySettings = field(
        default_factory=lambda: TrajectorySettings(joint_names=('joint',))
    )

    @property
    def samples(self) -> int:
        """Number of samples in the run (t_0 .. t_{n-1})."""
        return int(round(self.duration_s / self.common.dt_s))


class ClosedLoop:
    """Plant, observer, controller and drive gate, advanced one sample per ``step``."""

    def __init__(self, scenario: Scenario, batch: int | None = None):
        """Build the run.

        ``batch`` = n runs the same scenario n times at once (states are arrays).
        """
        dt = scenario.common.dt_s
        zero = 0.0 if batch is None else np.zeros(batch)
        self.scenario = scenario
        self.period_ns = period_ns(dt)
        self.joint = SimulatedJoint(
            scenario.plant,
            dt,
            position_rad=zero,
            velocity_rad_s=zero,
            encoder=None
            if scenario.encoder is None
            else Encoder.from_parameters(scenario.encoder),
            command_delay_samples=scenario.command_delay_samples,
            torque_time_constant_s=scenario.torque_time_constant_s,
        )
        self.plant = self.joint.plant
        self.eso = ExtendedStateObserver(scenario.eso, dt, x_hat0=(zero, zero, zero))
        self.pairing = ObserverInputPairing(
            self.eso, self.period_ns, self.eso.correction, SIM_PATIENCE_SAMPLES
        )
        law = make_controller(scenario.controller, scenario.gains, scenario.common)
        reference = make_reference(
            scenario.reference, max_deceleration=scenario.trajectory.max_deceleration
        )
        self.assembly = ControlSampleAssembly(
            law, reference, self.period_ns, needs_estimate=scenario.controller != 'pi'
        )
        common = scenario.common
        #: Goals and cancels by the stamp of the sample before which they are handed over.
        self.schedule: list[tuple[int, Goal | str]] = []
        self.goal_events: list[GoalEvent] = []
        self.execution: TrajectoryExecution | None = None
        if scenario.reference == 'hold' and batch is None:
            assert isinstance(reference, CommandedReference)  # make_reference's 'hold'
            self.execution = TrajectoryExecution(
                reference,
                scenario.trajectory,
                (common.theta1n, common.theta2n, common.current_limit_a),
            )
        self.gate = CommandGate(scenario.common.current_limit_a)
        self.gate.activate()
        self.joint.activate()
        self.sample_index = 0
        self.estimate: Estimate | None = None  # the newest the observer gave
        self.input_current_gain = self.eso.dt_s * self.eso.gains.theta1n  # as the ESO node has it

    def step(self, command_lost: bool = False, eso_integrates_applied: bool = False) -> dict:
        """Run sample k in the node order; return every recorded quantity of that sample.

        Fault injection for the real-time case (``late_commands``): ``command_lost`` keeps u(k)
        from the drive (its gate holds the previous command until its timeout, then 0 A and,
        later, the brake); ``eso_integrates_applied`` makes the observer integrate the current
        the drive's gate held instead of the commanded one.
        """
        stamp = self.sample_index * self.period_ns
        t = sample_time_s(stamp)
        y = self.joint.read(stamp).position_rad
        velocity = self.plant.velocity_rad_s
        truth = self.joint.truth()
        self.deliver_estimates(self.pairing.add_measurement(stamp, y))
        assert self.estimate is not None  # a measurement gives x_hat(k) (sim patience)
        x1_hat, x2_hat, x3_hat = self.estimate.x_hat
        sample = self.assembly.add_measurement(stamp, y)
        assert sample is not None  # x_hat(k) came first: the law runs at once
        if self.execution is not None:
            self._execute(sample)
        if not command_lost:
            self.gate.offer(sample.current_a, stamp, sample.safe_stop, stamp)
        held = self.gate.hold(stamp)
        self.joint.write(held.current_a, held.brake)
        self.deliver_estimates(
            self.pairing.add_command(
                stamp, held.current_a if eso_integrates_applied else sample.current_a
            )
        )
        self.sample_index += 1
        ref = sample.reference
        record = dict(
            zip(
                EXTRA_FIELDS,
                (
                    t,
                    NAN if ref is None else ref.position_rad,
                    NAN if ref is None else ref.velocity_rad_s,
                    NAN if ref is None else ref.acceleration_rad_s2,
                    y,
                    x1_hat,
                    x2_hat,
                    x3_hat,
                    velocity,
                    truth.disturbance_rad_s2,
                ),
            )
        )
        # A latched sample (the law did not run) records NaN, as the controller node publishes it.
        record.update(
            dict.fromkeys(ControlOutput._fields, NAN)
            if sample.output is None
            else sample.output._asdict()
        )
        record['current_a'] = sample.current_a
        record['status'] = sample.status
        return record

    def submit_at(self, stamp_ns: int, goal: Goal) -> None:
        """Hand ``goal`` over before the sample stamped ``stamp_ns`` (as the goal thread would)."""
        self.schedule.append((stamp_ns, goal))

    def cancel_at(self, stamp_ns: int, goal_id: str) -> None:
        """Cancel ``goal_id`` before the sample stamped ``stamp_ns``."""
        self.schedule.append((stamp_ns, goal_id))

    def _execute(self, sample) -> None:
        """Hand over what is due, then the execution's judgement of this sample (node order)."""
        assert self.execution is not None  # a commanded run
        due = [item for item in self.schedule if item[0] <= sample.stamp_ns]
        if due:
            self.schedule = [item for item in self.schedule if item[0] > sample.stamp_ns]
            for _, command in sorted(due, key=lambda item: item[0]):
                if isinstance(command, Goal):
                    self.execution.submit(command)
                else:
                    self.execution.cancel(command)
        ref = sample.reference
        desired = None if ref is None else DesiredState((ref[0],), (ref[1],), (ref[2],))
        estimate = sample.estimate
        velocities = (
            None if estimate is None or not self.assembly.needs_estimate else (estimate[0],)
        )
        self.execution.after_sample(
            sample.stamp_ns, sample.status, sample.t_s, desired, (sample.y,), velocities
        )
        self.goal_events.extend(self.execution.take_events())

    def deliver_estimates(self, estimates) -> None:
        """Hand the observer's new estimates to the controller, as the estimate topic does."""
        for estimate in estimates:
            self.estimate = estimate
            self.assembly.add_estimate(
                estimate.sample_ns,
                estimate.x_hat[1],
                estimate.x_hat[2],
                estimate.input_ns,
                estimate.input_current_a,
                self.input_current_gain,
            )

    def run(
        self, samples: int | None = None, stop_on_divergence: bool = True
    ) -> dict[str, np.ndarray]:
        """Run ``samples`` samples (default: the scenario's) and return the trace as arrays.

        A run whose state stops being finite, whose error passes ``DIVERGENCE_ERROR_RAD``, or
        whose controller latched its safe stop (every run of a batch) is cut at that sample
        (``stop_on_divergence``); the metrics then report it as diverged.
        """
        n = self.scenario.samples if samples is None else samples
        rows = []
        for _ in range(n):
            row = self.step()
            rows.append(row)
            if stop_on_divergence and not np.all(np.isfinite(row['measured_position_rad'])):
                break
            if stop_on_divergence and np.all(np.asarray(row['status']) == Status.LATCHED):
                break
            if stop_on_divergence and np.any(np.abs(row['error_rad']) > DIVERGENCE_ERROR_RAD):
                break
        return {name: np.array([r[name] for r in rows], dtype=float) for name in TRACE_FIELDS}
