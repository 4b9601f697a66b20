# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``cia402_torque_test``: the first low-torque run of a drive, without ROS.

    cia402_torque_test --eds my_drive.eds --channel can0 --current 0.5 --duration 2
    cia402_torque_test --interface hub --channel 127.0.0.1:PORT --simulated --current 0.5

Configures the joint (every check of ``Cia402Master.configure``), activates it, holds the
brake for ``--hold`` s, applies ``--current`` [A] for ``--duration`` s on the SYNC grid, then
deactivates (quick stop, ramp, brake, disable). Prints one line per phase and a summary
(samples, missed TPDOs, position range, mean torque actual). ``--acknowledge-fault`` resets a
drive fault after configure: the explicit, person-triggered reset. A fault reported by the
joint ends the run with exit code 1. Also what the tests kill -9 under a small torque.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Sequence

from actuator_core.joint import JointError
from actuator_cia402.config import DriverParameters
from actuator_cia402.joint import Cia402Joint


def run_on_grid(
    joint, current_a: float, hold_s: float, duration_s: float, period_s: float, on_sample=None
) -> dict:
    """Brake for ``hold_s``, then ``current_a`` for ``duration_s``, one cycle per period."""
    period_ns = int(round(period_s * 1e9))
    start = (time.time_ns() // period_ns + 2) * period_ns
    hold, total = int(round(hold_s / period_s)), int(round((hold_s + duration_s) / period_s))
    positions, efforts, missed, fault = [], [], 0, ''
    k = 0
    while k < total:
        t_k = start + k * period_ns
        wait_ns = t_k - time.time_ns()
        if wait_ns > 0:
            time.sleep(wait_ns * 1e-9)
        else:
            k = max(k, (time.time_ns() - start) // period_ns)  # overrun: no replay
            t_k = start + k * period_ns
        braked = k < hold
        joint.write(0.0 if braked else current_a, braked)
        sample = joint.read(t_k)
        k += 1
        if sample is None:
            missed += 1
            continue
        if on_sample is not None:
            on_sample(k, sample)
        if sample.fault:
            fault = sample.fault
            break
        positions.append(sample.position_rad)
        if not braked:
            efforts.append(sample.effort_nm)
    return {
        'samples': len(positions),
        'missed': missed,
        'fault': fault,
        'positions': positions,
        'efforts': efforts,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """CLI; exit 0 after a clean run, 1 on a joint fault, 2 on a refused configuration."""
    ap = argparse.ArgumentParser(prog='cia402_torque_test', description=__doc__.splitlines()[0])
    ap.add_argument('--interface', default='socketcan', choices=('socketcan', 'hub'))
    ap.add_argument('--channel', default='can0')
    ap.add_argument('--node-id', type=int, default=1)
    ap.add_argument('--master-node-id', type=int, default=127)
    ap.add_argument('--eds', default='')
    ap.add_argument('--simulated', action='store_true', help="the project's simulated drive")
    ap.add_argument('--current', type=float, default=0.5, help='motor current [A]')
    ap.add_argument('--hold', type=float, default=0.2, help='braked time before [s]')
    ap.add_argument('--duration', type=float, default=2.0, help='time at --current [s]')
    ap.add_argument('--sync-period', type=float, default=0.001)
    ap.add_argument('--no-sync-producer', action='store_true')
    ap.add_argument('--acknowledge-fault', action='store_true')
    args = ap.parse_args(argv)
    try:
        cfg = DriverParameters(
            node_id=args.node_id,
            interface=args.interface,
            channel=args.channel,
            eds_file=args.eds,
            simulated_drive=args.simulated,
            sync_period_s=args.sync_period,
            master_node_id=args.master_node_id,
            sync_producer=not args.no_sync_producer,
        )
    except ValueError as exc:
        print(f'cia402_torque_test: {exc}', file=sys.stderr)
        return 2
    joint = Cia402Joint(cfg)
    try:
        for note in joint.configure():
            print(f'configure: {note}', flush=True)
        if args.acknowledge_fault:
            print(f'acknowledge: {joint.acknowledge_fault()}', flush=True)
        joint.activate()
    except JointError as exc:
        print(f'cia402_torque_test: {exc}', file=sys.stderr)
        joint.close()
        return 2
    print(f'active: {args.current:g} A after {args.hold:g} s of brake', flush=True)
    announced = []

    def on_sample(k, sample):
        if not announced and k * args.sync_period > args.hold + 0.05:
            announced.append(k)
            print(
                f'applying {args.current:g} A: torque actual {sample.effort_nm:.3f} N m',
                flush=True,
            )

    result = run_on_grid(
        joint, args.current, args.hold, args.duration, args.sync_period, on_sample
    )
    for note in joint.deactivate():
        print(f'deactivate: {note}', flush=True)
    joint.cleanup()
    q, e = result['positions'] or [0.0], result['efforts'] or [0.0]
    print(
        f'samples {result["samples"]}, missed TPDOs {result["missed"]}, position '
        f'{min(q):.5f} .. {max(q):.5f} rad, mean torque actual {sum(e) / len(e):.3f} N m',
        flush=True,
    )
    if result['fault']:
        print(f'fault: {result["fault"]}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
