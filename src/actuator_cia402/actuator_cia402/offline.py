# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The offline core (actuator_sim.loop.ClosedLoop) with what the CiA 402 drive adds to the joint.

Explains the difference between a run through the driver and the offline core. The drive
(sim_drive.py) applies the RPDO at the next SYNC (one sample of command delay, as any
synchronous CANopen drive), follows it with a first-order torque loop (tau), and the angle
comes back quantised to encoder counts. All three are parts of the one simulated joint
(``actuator_plant.sim_joint.SimulatedJoint``: ``CommandDelay``, ``torque_loop``, ``Encoder``),
set through the scenario; each can be switched off to see its share. The default scenario is
the one the CiA 402 joints run, ``drive_pp_nftsmc_eso`` (Case 2 tuned for the drive's delay):

    python -m actuator_cia402.offline --duration 5 [--scenario case2_pp_nftsmc_eso]

``--margin`` shows how little the drive leaves the paper's design: samples at the current limit
over a long run for observer bandwidths around the paper's 60 rad/s and slower torque loops
(docs/cia402.md#tuned-for-the-drives-delay).
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any, Sequence

import numpy as np

from actuator_cia402.sim_settings import SimDriveSettings
from actuator_core import limits
from actuator_plant.encoder import EncoderParameters
from actuator_sim.scenarios import DRIVE_DELAY_SAMPLES, DRIVE_SCENARIO, PAPER_SCENARIO

#: The simulated drive's encoder: counts per motor revolution (EDS 0x608F).
MOTOR_COUNTS_PER_REV = 4096


def drive_scenario(
    scenario,
    delay_syncs: int = DRIVE_DELAY_SAMPLES,
    tau_s: float | None = None,
    quantise: bool = True,
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
    scenario_name: str = DRIVE_SCENARIO,
    duration_s: float = 5.0,
    delay_syncs: int = DRIVE_DELAY_SAMPLES,
    tau_s: float | None = None,
    quantise: bool = True,
    omega0_rad_s: float | None = None,
) -> dict[str, np.ndarray]:
    """Run the offline closed loop of a scenario with the drive effects; returns the trace.

    ``omega0_rad_s``: the observer bandwidth w0 of (15) instead of the scenario's.
    """
    from actuator_sim.loop import ClosedLoop
    from actuator_sim.params_yaml import all_scenarios

    scenario = dataclasses.replace(all_scenarios()[scenario_name], duration_s=duration_s)
    if omega0_rad_s is not None:
        scenario.eso = dataclasses.replace(scenario.eso, omega0_rad_s=omega0_rad_s)
    # a chattering run is what this measures: it is not cut as diverged
    return ClosedLoop(drive_scenario(scenario, delay_syncs, tau_s, quantise)).run(
        stop_on_divergence=False
    )


def window_errors(trace: dict[str, np.ndarray], start_s: float = 1.0) -> tuple[float, float]:
    """Max |e| and RMS e [rad] from ``start_s`` on (after the envelope's initial transient)."""
    e = trace['error_rad'][trace['t_s'] >= start_s]
    return float(np.max(np.abs(e))), float(np.sqrt(np.mean(e**2)))


def samples_at_limit(trace: dict[str, np.ndarray], start_s: float = 1.0) -> int:
    """Count the samples from ``start_s`` on commanded at the current limit (either sign)."""
    current = trace['current_a'][trace['t_s'] >= start_s]
    return int(np.count_nonzero(np.abs(current) >= limits.CURRENT_LIMIT_A - 1e-9))


#: Observer bandwidths [rad/s] and torque-loop time constants [s] of the margin table: around the
#: paper's w0 = 60 rad/s (Table 4) and from the simulated drive's 0.2 ms up, as a stand-in for
#: lag a real drive or a late host adds to its one SYNC.
MARGIN_BANDWIDTHS_RAD_S = (50.0, 55.0, 60.0, 65.0, 70.0, 80.0)
MARGIN_TORQUE_LAGS_S = (2.0e-4, 5.0e-4, 1.0e-3)


def margin_table(
    scenario_name: str = PAPER_SCENARIO,
    duration_s: float = 40.0,
    bandwidths_rad_s: Sequence[float] = MARGIN_BANDWIDTHS_RAD_S,
    torque_lags_s: Sequence[float] = MARGIN_TORQUE_LAGS_S,
) -> list[tuple[float, float, int, float]]:
    """Return (w0, tau, samples at the limit, max |e|) of one SYNC of delay over ``duration_s``."""
    rows = []
    for omega0 in bandwidths_rad_s:
        for tau in torque_lags_s:
            trace = run(scenario_name, duration_s, tau_s=tau, omega0_rad_s=omega0)
            rows.append((omega0, tau, samples_at_limit(trace), window_errors(trace)[0]))
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: the offline core with each drive effect added in turn."""
    parser = argparse.ArgumentParser(
        prog='actuator_cia402.offline', description=__doc__.splitlines()[0]
    )
    parser.add_argument('--duration', type=float, default=5.0)
    parser.add_argument(
        '--scenario',
        default=None,
        help=f"scenario (default {DRIVE_SCENARIO}; with --margin {PAPER_SCENARIO}, the paper's)",
    )
    parser.add_argument(
        '--margin',
        action='store_true',
        help='samples at the current limit for observer bandwidths and torque lags (40 s each)',
    )
    args = parser.parse_args(argv)
    if args.margin:
        name = args.scenario or PAPER_SCENARIO
        print(f'{name}, one SYNC of command delay, t >= 1 s of 40 s:')
        for omega0, tau, at_limit, peak in margin_table(name):
            print(
                f'w0 {omega0:5.1f} rad/s, torque lag {tau * 1e3:3.1f} ms: {at_limit:6d} samples '
                f'at the current limit, max |e| {peak:.2e} rad'
            )
        return 0
    cases: list[tuple[str, dict[str, Any]]] = [
        ('offline core', dict(delay_syncs=0, tau_s=0.0, quantise=False)),
        ('+ quantisation', dict(delay_syncs=0, tau_s=0.0, quantise=True)),
        ('+ torque loop', dict(delay_syncs=0, quantise=True)),
        ('+ one SYNC delay (the drive)', dict(delay_syncs=1, quantise=True)),
    ]
    print(args.scenario or DRIVE_SCENARIO)
    for name, kwargs in cases:
        peak, rms = window_errors(run(args.scenario or DRIVE_SCENARIO, args.duration, **kwargs))
        print(f'{name:30s} max |e| {peak:.3e} rad, RMS {rms:.3e} rad (t >= 1 s)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
