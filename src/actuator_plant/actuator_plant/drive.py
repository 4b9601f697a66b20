# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What a drive adds between the command and the joint: command delay and a torque loop.

Composable parts of the simulated joint (``actuator_plant.sim_joint``), each off by default.

Command delay: the joint applies u(k - D), D samples after it was commanded. D = 0 is the
paper's loop. D = 1 or 2 models a drive that takes the command one or two
samples late (a bus cycle, a late callback); the observer still integrates the commanded
current u(k), which is the ``plant_delay`` of ``actuator_sim.stability``. Before the first
D commands exist the plant applies 0 A. D may be an integer array (one delay per element of
a batch); each element then picks its own entry of the same history.
"""

from __future__ import annotations

import math

import numpy as np

from actuator_core.limits import COMMAND_DELAY_MAX_SAMPLES
from actuator_core.params import check_value


class CommandDelay:
    """Shift register of the last D commands: ``apply(u(k))`` returns u(k - D)."""

    def __init__(self, samples, zero=0.0):
        """Delay by ``samples`` (int or int array, 0..COMMAND_DELAY_MAX_SAMPLES).

        ``zero`` is 0 A of the run's shape.
        """
        check_value(
            'command_delay_samples',
            samples,
            {
                'low': 0.0,
                'high': float(COMMAND_DELAY_MAX_SAMPLES),
                'low_open': False,
                'unit': 'samples',
                'description': 'samples between command and application',
            },
        )
        delays = np.asarray(samples)
        if not np.all(delays == np.round(delays)):
            raise ValueError(f'command_delay_samples must be whole samples, got {samples}')
        self.samples = delays.astype(int) if delays.ndim else int(delays)
        self.history = [zero] * int(np.max(delays))

    def apply(self, current_a):
        """Push u(k) [A]; return u(k - D) [A], the current the plant holds over sample k."""
        candidates = [current_a] + self.history
        if np.ndim(self.samples) == 0:
            out = candidates[self.samples]
        else:
            out = np.choose(
                self.samples, [np.broadcast_to(c, np.shape(self.samples)) for c in candidates]
            )
        if self.history:
            self.history = candidates[:-1]
        return out


def torque_loop(current_a, target_a, dt_s: float, tau_s: float):
    """First-order torque loop over one period: (mean current, end current) [A].

    i(t) = i* + (i0 - i*) exp(-t / tau); ``tau_s`` = 0 applies the target at once.
    """
    if tau_s <= 0.0:
        return target_a, target_a
    decay = math.exp(-dt_s / tau_s)
    mean = target_a + (current_a - target_a) * (tau_s / dt_s) * (1.0 - decay)
    return mean, target_a + (current_a - target_a) * decay
