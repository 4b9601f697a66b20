# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``cia402_torque_test``: the first low-torque run of a drive, without ROS.

    cia402_torque_test --eds my_drive.eds --channel can0 --current-limit 0.5 --velocity-limit 1
        --brake-status-index 0 --quick-stop-deceleration 20 --current 0.3 --duration 2
    cia402_torque_test --interface hub --channel 127.0.0.1:PORT --simulated --current 0.3

Writes ``--current-limit`` to the drive as 0x6072/0x6073 and ``--velocity-limit`` as 0x6080
(and refuses a ``--current`` above the limit), configures the joint (every check of
``Cia402Master.configure``), activates it, holds the brake for ``--hold`` s, then applies
``--current`` [A] on the SYNC grid (paced on the monotonic clock) for ``--duration`` s. Its
first ``sign_check.WINDOW_S`` are the sign check: the joint must move the current's way, else
the run stops with a one-line refusal. The joint's speed beyond ``--velocity-limit`` stops it
too. Whatever ends the run (its end, a fault, a refusal, Ctrl-C or SIGTERM), the joint ends
control and deactivates (braked cycles, then quick stop, brake, disable voltage), and the tool
prints what the drive did. One line per phase and a summary (samples, missed TPDOs, position
range, mean torque actual). ``--acknowledge-fault`` resets a drive fault after configure: the
explicit, person-triggered reset. Exit 0 after a clean run, 1 on a joint fault, 2 on a refused
configuration, 3 on a failed sign check or the speed limit, 130 when interrupted.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from typing import Callable, Optional, Sequence

from actuator_cia402.config import DriverParameters, check_real_drive
from actuator_cia402.joint import Cia402Joint
from actuator_cia402.sign_check import WINDOW_S, SignCheck
from actuator_core.joint import JointError, JointSettings, SoftLimits

EXIT_FAULT, EXIT_REFUSED, EXIT_STOPPED, EXIT_INTERRUPTED = 1, 2, 3, 130


def run_on_grid(
    joint,
    current_a: float,
    hold_s: float,
    duration_s: float,
    period_s: float,
    on_sample=None,
    judge: Optional[Callable[[float, object], str]] = None,
) -> dict:
    """Brake for ``hold_s``, then ``current_a`` for ``duration_s``, one cycle per period.

    Paced on the monotonic clock (a wall-clock step moves nothing); a late cycle is skipped,
    not replayed. ``judge(seconds at the current, sample)`` may stop the run with a reason. A
    fault or a judge's reason ends control at once (``joint.end_control``).
    """
    period_ns = int(round(period_s * 1e9))
    start = (time.monotonic_ns() // period_ns + 2) * period_ns
    hold, total = int(round(hold_s / period_s)), int(round((hold_s + duration_s) / period_s))
    positions, efforts, missed, fault, stopped = [], [], 0, '', ''
    k = 0
    while k < total:
        t_k = start + k * period_ns
        wait_ns = t_k - time.monotonic_ns()
        if wait_ns > 0:
            time.sleep(wait_ns * 1e-9)
        else:
            k = max(k, (time.monotonic_ns() - start) // period_ns)  # overrun: no replay
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
        fault = sample.fault
        stopped = '' if fault or braked or judge is None else judge((k - hold) * period_s, sample)
        if fault or stopped:
            joint.end_control(fault or stopped)
            break
        positions.append(sample.position_rad)
        if not braked:
            efforts.append(sample.effort_nm)
    return {
        'samples': len(positions),
        'missed': missed,
        'fault': fault,
        'stopped': stopped,
        'positions': positions,
        'efforts': efforts,
    }


def parser() -> argparse.ArgumentParser:
    """Return the command line."""
    ap = argparse.ArgumentParser(prog='cia402_torque_test', description=__doc__.splitlines()[0])
    ap.add_argument('--interface', default='socketcan', choices=('socketcan', 'hub'))
    ap.add_argument('--channel', default='can0')
    ap.add_argument('--node-id', type=int, default=1)
    ap.add_argument('--master-node-id', type=int, default=127)
    ap.add_argument('--eds', default='')
    ap.add_argument('--simulated', action='store_true', help="the project's simulated drive")
    ap.add_argument('--current', type=float, default=0.3, help='motor current [A]')
    ap.add_argument(
        '--current-limit',
        type=float,
        default=1.0,
        help='written to the drive as 0x6072/0x6073 [A]; a larger --current is refused',
    )
    ap.add_argument(
        '--velocity-limit',
        type=float,
        default=1.0,
        help='joint speed written to the drive as 0x6080; the run stops beyond it [rad/s]',
    )
    ap.add_argument('--polarity', type=int, default=0, help='0x607E as set in the drive tool')
    ap.add_argument(
        '--brake-status-index',
        type=lambda text: int(text, 0),
        default=-1,
        help='object whose bit reads 1 while the brake is closed (0: none; required on a '
        'real drive)',
    )
    ap.add_argument(
        '--brake-status-mask', type=lambda text: int(text, 0), default=0, help='its bit mask'
    )
    ap.add_argument(
        '--quick-stop-deceleration',
        type=float,
        default=0.0,
        help='joint deceleration of a quick stop, written as 0x6085 [rad/s^2] (required on a '
        'real drive)',
    )
    ap.add_argument('--hold', type=float, default=0.2, help='braked time before [s]')
    ap.add_argument('--duration', type=float, default=2.0, help='time at --current [s]')
    ap.add_argument('--sync-period', type=float, default=0.001)
    ap.add_argument('--no-sync-producer', action='store_true')
    ap.add_argument('--acknowledge-fault', action='store_true')
    return ap


def parameters(args) -> DriverParameters:
    """Return the driver's parameters from the command line (ValueError: one-line refusal)."""
    if abs(args.current) > args.current_limit:
        raise ValueError(
            f'--current {args.current:g} A is above --current-limit {args.current_limit:g} A '
            '(written to the drive as 0x6072/0x6073): refused'
        )
    if args.current == 0.0:
        raise ValueError('--current 0 A cannot show the direction: give a small current')
    cfg = DriverParameters(
        node_id=args.node_id,
        interface=args.interface,
        channel=args.channel,
        eds_file=args.eds,
        simulated_drive=args.simulated,
        sync_period_s=args.sync_period,
        master_node_id=args.master_node_id,
        sync_producer=not args.no_sync_producer,
        current_limit_a=args.current_limit,
        velocity_limit_rad_s=args.velocity_limit,
        polarity=args.polarity,
        brake_status_index=args.brake_status_index,
        brake_status_mask=args.brake_status_mask,
        quick_stop_deceleration_rad_s2=args.quick_stop_deceleration,
    )
    check_real_drive(cfg)
    cfg.eds_path()
    return cfg


def judge_run(current_a: float, velocity_limit_rad_s: float, period_s: float):
    """Return the run's judge: the sign check first, the speed limit throughout."""
    check = SignCheck(current_a)
    speed = SoftLimits(
        JointSettings(sample_time_s=period_s, velocity_max_rad_s=velocity_limit_rad_s)
    )

    def judge(elapsed_s: float, sample) -> str:
        if 'speed' in (over := speed.check(sample.stamp_ns, sample.position_rad)):
            return f'{over}: stopped'
        before = check.verdict
        verdict = check.update(elapsed_s, sample.position_rad)
        if verdict == 'right' and not before:
            print(check.line(), flush=True)
        return '' if verdict in ('', 'right') else verdict

    return judge


def _interrupt(signum, frame) -> None:
    """SIGTERM as Ctrl-C: the run's finally stops the drive."""
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    """CLI; exit codes in the module docstring."""
    args = parser().parse_args(argv)
    try:
        cfg = parameters(args)
    except ValueError as exc:
        print(f'cia402_torque_test: {exc}', file=sys.stderr)
        return EXIT_REFUSED
    signal.signal(signal.SIGTERM, _interrupt)
    joint = Cia402Joint(cfg)
    code = 0
    try:
        for note in joint.configure():
            print(f'configure: {note}', flush=True)
        if args.acknowledge_fault:
            print(f'acknowledge: {joint.acknowledge_fault()}', flush=True)
        joint.activate()
        code = _run(joint, args)
    except JointError as exc:
        print(f'cia402_torque_test: {exc}', file=sys.stderr)
        code = EXIT_REFUSED
    except KeyboardInterrupt:
        print('interrupted: stopping the drive', flush=True)
        code = EXIT_INTERRUPTED
    finally:
        _stop(joint)
    return code


def _run(joint: Cia402Joint, args) -> int:
    """Hold the brake, then the current under the judge; print the summary; the exit code."""
    print(f'active: {args.current:g} A after {args.hold:g} s of brake', flush=True)
    announced: list[int] = []  # the sample the current was announced at

    def on_sample(k, sample):
        if not announced and k * args.sync_period > args.hold + 0.05:
            announced.append(k)
            print(
                f'applying {args.current:g} A: torque actual {sample.effort_nm:.3f} N m',
                flush=True,
            )

    judge = judge_run(args.current, args.velocity_limit, args.sync_period)
    if args.duration < WINDOW_S:
        print(f'--duration {args.duration:g} s is shorter than the sign check: it may refuse')
    result = run_on_grid(
        joint, args.current, args.hold, args.duration, args.sync_period, on_sample, judge
    )
    q, e = result['positions'] or [0.0], result['efforts'] or [0.0]
    print(
        f'samples {result["samples"]}, missed TPDOs {result["missed"]}, position '
        f'{min(q):.5f} .. {max(q):.5f} rad, mean torque actual {sum(e) / len(e):.3f} N m',
        flush=True,
    )
    if result['fault']:
        print(f'fault: {result["fault"]}', file=sys.stderr)
        return EXIT_FAULT
    if result['stopped']:
        print(f'cia402_torque_test: {result["stopped"]}', file=sys.stderr)
        return EXIT_STOPPED
    return 0


def _stop(joint: Cia402Joint) -> None:
    """End control and deactivate, whatever ended the run; print what the drive did."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the stop itself is not interrupted
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if joint.active and not joint.stop_report:
        joint.end_control('the run ended')
    report = joint.stop_report
    for note in joint.close():
        print(f'stop: {note}', flush=True)
    if report:
        print(f'control ended: {report}', flush=True)
        print(f'deactivated: {joint.describe()}', flush=True)


if __name__ == '__main__':
    sys.exit(main())
