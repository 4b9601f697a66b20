# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The offline core (actuator_sim.loop.ClosedLoop) with what the CiA 402 drive adds to the joint.

Explains the difference between a run through the driver and the offline core. The drive
(sim_drive.py) applies the RPDO at the next SYNC (one sample of command delay, as any
synchronous CANopen drive), follows it with a first-order torque loop (tau), and the angle
comes back quantised to encoder counts. All three are parts of the one simulated joint
(``actuator_plant.sim_joint.SimulatedJoint``: ``CommandDelay``, ``torque_loop``, ``Encoder``),
set through the scenario; each can be switched off to see its share:

    python -m actuator_cia402.offline --duration 5
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Sequence

import numpy as np

from actuator_core import limits
from actuator_plant.encoder import EncoderParameters
from actuator_cia402.config import SimDriveSettings

#: The simulated drive's encoder: counts per motor revolution (EDS 0x608F).
MOTOR_COUNTS_PER_REV = 4096


def drive_scenario(
    scenario, delay_syncs: int = 1, tau_s: float | None = None, quantise: bool = True
):
    """``scenario`` with the drive's command delay, torque loop and encoder counts."""
    tau = SimDriveSettings().torque_time_constant_s if tau_s is None else tau_s
    counts = MOTOR_COUNTS_PER_REV * limits.NOMINAL_GEAR_RATIO if quantise else 0
    return dataclasses.replace(
        scenario,
        command_delay_samples=delay_syncs,
        torque_time_constant_s=tau,
        encoder=EncoderParameters(counts_per_rev=counts) if quantise else None,
    )


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

    scenario = dataclasses.replace(all_scenarios()[scenario_name], duration_s=duration_s)
    return ClosedLoop(drive_scenario(scenario, delay_syncs, tau_s, quantise)).run()


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
