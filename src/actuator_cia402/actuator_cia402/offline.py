# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The offline core (actuator_sim.loop.ClosedLoop) with what the CiA 402 drive adds to the plant.

Explains the difference between a run through the driver and the offline core: the drive
(sim_drive.py) applies the RPDO at the next SYNC (one sample of command delay, as any
synchronous CANopen drive), follows it with a first-order torque loop (tau), and the angle
comes back quantised to encoder counts. Each effect can be switched off to see its share:

    python -m actuator_cia402.offline --duration 5
"""

from __future__ import annotations

import argparse
from collections import deque
from typing import Sequence

import numpy as np

from actuator_plant.model import JointPlant
from actuator_cia402.config import DriverParameters, SimDriveSettings
from actuator_cia402.scaling import Scaling
from actuator_cia402.sim_drive import torque_loop


class DrivePlant:
    """A JointPlant behind the drive: command delay in SYNCs, torque loop, encoder quantisation."""

    def __init__(self, plant: JointPlant, scaling: Scaling | None, tau_s: float, delay_syncs: int):
        """Wrap ``plant``; ``scaling`` None reports the exact angle."""
        self.plant, self.scaling, self.tau_s = plant, scaling, tau_s
        self.queue = deque([0.0] * delay_syncs)
        self.current_a = 0.0

    @property
    def position_rad(self) -> float:
        """Position actual 0x6064 as the driver converts it back: counts * 2 pi / (cpr N)."""
        q = self.plant.position_rad
        return (
            q
            if self.scaling is None
            else self.scaling.counts_to_rad(self.scaling.rad_to_counts(q))
        )

    @property
    def velocity_rad_s(self) -> float:
        """True joint velocity (only the trace records it)."""
        return self.plant.velocity_rad_s

    def truth(self, current_a):
        """Ground truth of the joint, with the current actually flowing."""
        return self.plant.truth(self.current_a)

    def step(self, current_a: float) -> None:
        """Put the command into the delay line.

        The drive integrates the one it latched at this SYNC.
        """
        self.queue.append(current_a)
        target = self.queue.popleft()
        mean, self.current_a = torque_loop(self.current_a, target, self.plant.dt_s, self.tau_s)
        self.plant.step(mean)


def run(
    scenario_name: str = 'case2_pp_nftsmc_eso',
    duration_s: float = 5.0,
    delay_syncs: int = 1,
    tau_s: float | None = None,
    quantise: bool = True,
) -> dict[str, np.ndarray]:
    """Run the offline closed loop of a scenario with the drive effects; returns the trace."""
    from actuator_sim.loop import ClosedLoop
    from actuator_sim.params_yaml import all_scenarios

    scenario = all_scenarios()[scenario_name]
    scenario.duration_s = duration_s
    loop = ClosedLoop(scenario)
    tau = SimDriveSettings().torque_time_constant_s if tau_s is None else tau_s
    loop.plant = DrivePlant(
        loop.plant, DriverParameters().scaling if quantise else None, tau, delay_syncs
    )
    return loop.run()


def window_errors(trace: dict[str, np.ndarray], start_s: float = 1.0) -> tuple[float, float]:
    """Max |e| and RMS e [rad] from ``start_s`` on (after the envelope's initial transient)."""
    e = trace['error_rad'][trace['t_s'] >= start_s]
    return float(np.max(np.abs(e))), float(np.sqrt(np.mean(e**2)))


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: the offline core with each drive effect added in turn."""
    parser = argparse.ArgumentParser(
        prog='actuator_cia402.offline', description=__doc__.splitlines()[0]
    )
    parser.add_argument('--duration', type=float, default=5.0)
    args = parser.parse_args(argv)
    cases = [
        ('offline core', dict(delay_syncs=0, tau_s=0.0, quantise=False)),
        ('+ quantisation', dict(delay_syncs=0, tau_s=0.0, quantise=True)),
        ('+ torque loop', dict(delay_syncs=0, quantise=True)),
        ('+ one SYNC delay (the drive)', dict(delay_syncs=1, quantise=True)),
    ]
    for name, kwargs in cases:
        peak, rms = window_errors(run(duration_s=args.duration, **kwargs))
        print(f'{name:30s} max |e| {peak:.3e} rad, RMS {rms:.3e} rad (t >= 1 s)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
