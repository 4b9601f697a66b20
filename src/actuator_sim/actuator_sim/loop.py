"""The one closed-loop core: plant, ESO and controller stepped in the order the ROS nodes use.

Sample k (see docs/architecture.md):
  1. the plant is sampled: y(k) = q(t_k);
  2. the controller computes u(k) from y(k), x_hat(k) and the reference at t_k;
  3. the ESO integrates the pair (y(k), u(k)) to x_hat(k+1);
  4. the plant integrates [t_k, t_k+1) with u(k) held.
The nodes call exactly these functions in exactly this order, so a run in deterministic sim
time reproduces an offline run sample by sample (``tests/test_sim_time_equivalence.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from actuator_core.limits import DIVERGENCE_ERROR_RAD
from actuator_core.timing import period_ns, sample_time_s
from actuator_controller.laws import CommonConfig, Controller, ControlOutput, make_controller
from actuator_controller.reference import Reference, make_reference
from actuator_eso.observer import EsoGains, ExtendedStateObserver
from actuator_plant.encoder import Encoder, EncoderParameters
from actuator_plant.model import JointPlant, PlantParameters
from actuator_sim.delay import CommandDelay

#: Per-sample quantities recorded besides the controller's own ControlOutput fields.
EXTRA_FIELDS = ('t_s', 'reference_position_rad', 'reference_velocity_rad_s', 'reference_acceleration_rad_s2',
                'measured_position_rad', 'x1_hat_rad', 'x2_hat_rad_s', 'x3_hat_rad_s2',
                'true_velocity_rad_s', 'true_disturbance_rad_s2')
TRACE_FIELDS = EXTRA_FIELDS + ControlOutput._fields


@dataclass
class Scenario:
    """A closed-loop run: plant, observer, controller, reference and duration."""

    name: str
    controller: str = 'pp_nftsmc_eso'
    reference: str = 'fast'
    plant: PlantParameters = field(default_factory=PlantParameters)
    eso: EsoGains = field(default_factory=EsoGains)
    gains: object = None
    common: CommonConfig = field(default_factory=CommonConfig)
    duration_s: float = 10.0
    #: Encoder between the joint and the controller/ESO (None: the exact angle, as in the paper).
    encoder: EncoderParameters | None = None
    #: Samples between a command and its application by the plant (0: the paper's loop).
    command_delay_samples: int = 0

    @property
    def samples(self) -> int:
        """Number of samples in the run (t_0 .. t_{n-1})."""
        return int(round(self.duration_s / self.common.dt_s))


class ClosedLoop:
    """Plant + ESO + controller + reference, advanced one sample per ``step``."""

    def __init__(self, scenario: Scenario, batch: int | None = None):
        """Build the run; ``batch`` = n runs the same scenario n times at once (states are arrays)."""
        dt = scenario.common.dt_s
        zero = 0.0 if batch is None else np.zeros(batch)
        self.scenario = scenario
        self.period_ns = period_ns(dt)
        self.plant = JointPlant(scenario.plant, dt, position_rad=zero, velocity_rad_s=zero)
        self.eso = ExtendedStateObserver(scenario.eso, dt, x_hat0=(zero, zero, zero))
        self.controller: Controller = make_controller(scenario.controller, scenario.gains, scenario.common)
        self.reference: Reference = make_reference(scenario.reference)
        self.sample_index = 0
        self.last_current = zero
        self.encoder = None if scenario.encoder is None else Encoder.from_parameters(scenario.encoder)
        self.command_delay = CommandDelay(scenario.command_delay_samples, zero) \
            if np.any(np.asarray(scenario.command_delay_samples) != 0) else None

    def step(self, command_late: bool = False, eso_integrates_applied: bool = False) -> dict:
        """Run sample k in the node order; return every recorded quantity of that sample.

        Fault injection for the real-time case (``late_commands``): ``command_late`` makes the
        plant hold the previous current over this sample, as when a command misses its sample;
        ``eso_integrates_applied`` makes the ESO integrate that held current instead of the
        commanded one.
        """
        t = sample_time_s(self.sample_index * self.period_ns)
        y, velocity = self.plant.position_rad, self.plant.velocity_rad_s
        if self.encoder is not None:
            y = self.encoder.measure(y)
        truth = self.plant.truth(self.last_current)
        x1_hat, x2_hat, x3_hat = self.eso.state
        ref = self.reference.sample(t)
        out = self.controller.update(t, y, x2_hat, x3_hat, ref)
        applied = self.last_current if command_late else out.current_a
        if self.command_delay is not None:
            applied = self.command_delay.apply(applied)
        self.eso.update(y, applied if eso_integrates_applied else out.current_a)
        self.plant.step(applied)
        self.last_current = applied
        self.sample_index += 1
        record = dict(zip(EXTRA_FIELDS, (t, ref.position_rad, ref.velocity_rad_s, ref.acceleration_rad_s2, y,
                                         x1_hat, x2_hat, x3_hat, velocity,
                                         truth.disturbance_rad_s2)))
        record.update(out._asdict())
        return record

    def run(self, samples: int | None = None, stop_on_divergence: bool = True) -> dict[str, np.ndarray]:
        """Run ``samples`` samples (default: the scenario's) and return the trace as arrays.

        A run whose state stops being finite is cut at that sample (``stop_on_divergence``);
        the metrics then report it as diverged instead of a number.
        """
        n = self.scenario.samples if samples is None else samples
        rows = []
        for _ in range(n):
            row = self.step()
            rows.append(row)
            if stop_on_divergence and not np.all(np.isfinite(row['measured_position_rad'])):
                break
            if stop_on_divergence and np.any(np.abs(row['error_rad']) > DIVERGENCE_ERROR_RAD):
                break
        return {name: np.array([r[name] for r in rows], dtype=float) for name in TRACE_FIELDS}

