# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The simulated joint behind the joint contract (``actuator_core.joint``).

A ``JointPlant`` (eq. (1)-(7), (40)-(42), the holding brake) with optional drive effects as
composable parts: a command delay of D samples and a first-order torque loop
(``actuator_plant.drive``), and an encoder (``actuator_plant.encoder``). All off by default,
which is the paper's loop. Held alike by the plant node, the offline loop and the CiA 402
simulated drive, so every one of them runs the same joint. Works on floats and, elementwise,
on numpy arrays (a batch of offline runs).
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from actuator_core.joint import Joint, JointSample
from actuator_plant.drive import CommandDelay, torque_loop
from actuator_plant.encoder import Encoder
from actuator_plant.model import JointPlant, PlantParameters


class SimulatedJoint(Joint):
    """Joint model, drive effects and encoder, advanced one sample per read."""

    kind = 'plant'
    replays_missed = True
    supports_sim_time = True

    def __init__(
        self,
        params: PlantParameters,
        dt_s: float,
        position_rad=0.0,
        velocity_rad_s=0.0,
        encoder: Optional[Encoder] = None,
        command_delay_samples=0,
        torque_time_constant_s: float = 0.0,
    ):
        """Build the joint at rest at ``position_rad``; every drive effect is optional."""
        self.plant = JointPlant(
            params, dt_s, position_rad=position_rad, velocity_rad_s=velocity_rad_s
        )
        # a float, or in a batch an array (Any: the same arithmetic serves both)
        zero: Any = 0.0 * np.asarray(position_rad) if np.ndim(position_rad) else 0.0
        self.encoder = encoder
        self.delay = (
            CommandDelay(command_delay_samples, zero)
            if np.any(np.asarray(command_delay_samples) != 0)
            else None
        )
        self.torque_time_constant_s = torque_time_constant_s
        self.torque_per_amp_nm = (
            params.nominal.torque_constant_nm_a * params.nominal.gear_ratio
        )  # k_tn N: motor current -> torque at the joint shaft
        self.applied_a = zero  # mean current over the interval before the newest sample
        self.brake = True  # the brake over that interval
        self._flowing_a = zero  # the torque loop's current at the newest sample
        self.command = (zero, True)  # what was written last: (current, brake)
        self._sampled = False

    def activate(self) -> list[str]:
        """Make the first read after activation sample without integrating."""
        self._sampled = False
        return []

    def write(self, current_a, brake) -> None:
        """Hold ``current_a`` [A] (and the brake where engaged) from now on."""
        self.command = (current_a, brake)

    def read(self, stamp_ns: int) -> JointSample:
        """Integrate the interval since the previous read, then sample y(k)."""
        if self._sampled:
            self._advance()
        self._sampled = True
        q = self.plant.position_rad
        y = q if self.encoder is None else self.encoder.measure(q)
        return JointSample(stamp_ns, y, self.torque_per_amp_nm * self.applied_a)

    def _advance(self) -> None:
        """One sample of eq. (1) with the written command through delay and torque loop."""
        target, brake = self.command
        if self.delay is not None:
            target = self.delay.apply(target)
        mean, self._flowing_a = torque_loop(
            self._flowing_a, target, self.plant.dt_s, self.torque_time_constant_s
        )
        self.plant.step(mean, brake)
        self.applied_a, self.brake = mean, brake

    def truth(self):
        """Ground truth at the newest sample with the current applied over the interval before."""
        return self.plant.truth(self.applied_a)

    def diagnostics(self) -> dict[str, str]:
        """Sample index and simulated time."""
        return {
            'sample': str(self.plant.sample_index),
            'sim_time_s': f'{self.plant.time_s:.3f}',
            'brake': str(bool(np.any(self.brake))),
        }
