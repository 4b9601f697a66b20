# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``cia402_sim_drive``: simulated CiA 402 drives in a process of their own, with their CAN hub.

    cia402_sim_drive --port 0 --node-id 1 [--node-id 2] [--inject sto@2.0] ...

Prints ``bus hub on 127.0.0.1:PORT`` (the channel the master connects to), ``drive N ready``
per drive, then one line per drive event (enable, brake, ramps, heartbeat loss, faults). It
runs until SIGINT or SIGTERM, whatever the master does: a killed master leaves the drive
running, as on a real bus. ROS-free; the hub binds 127.0.0.1 only.
"""

from __future__ import annotations

import argparse
import dataclasses
import faulthandler
import signal
import sys
import threading
from typing import Sequence

import canopen

from actuator_cia402.busload import frame_bits
from actuator_cia402.config import RATED_CURRENT_A, RATED_TORQUE_NM, default_eds
from actuator_cia402.hub import Hub, error_frame
from actuator_cia402.scaling import Scaling
from actuator_cia402.sim_drive import SimulatedDrive
from actuator_cia402.sim_faults import (
    FAULT_CODES,
    INJECTIONS,
    FaultPlan,
    Quirks,
    mapping_entry,
    plant_parameters,
)
from actuator_cia402.sim_settings import SimDriveSettings
from actuator_core import limits
from actuator_ros.realtime import RealtimeSettings  # ROS-free: yaml only, no rclpy


def _injection(text: str) -> tuple[str, float]:
    """'kind@t' -> (kind, t)."""
    kind, _, at = text.partition('@')
    if kind not in INJECTIONS or not at:
        raise argparse.ArgumentTypeError(
            f'--inject takes KIND@T_S with KIND one of {", ".join(INJECTIONS)}; got {text!r}'
        )
    return kind, float(at)


def _mapping_entry(text: str):
    """'1A01:3' -> (0x1A01, 3) for argparse."""
    try:
        return mapping_entry(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _priority(text: str) -> int:
    """Return a SCHED_FIFO priority 0-99 (0 = normal scheduling) from the command line."""
    value = int(text)
    if not 0 <= value <= 99:
        raise argparse.ArgumentTypeError(f'--thread-priority takes 0-99, got {value}')
    return value


def _described(name: str) -> str:
    """Return the description of a SimDriveSettings field (the one source of its meaning)."""
    return {f.name: f.metadata['description'] for f in dataclasses.fields(SimDriveSettings)}[name]


def parser() -> argparse.ArgumentParser:
    """Return the command line."""
    ap = argparse.ArgumentParser(prog='cia402_sim_drive', description=__doc__.splitlines()[0])
    ap.add_argument('--port', type=int, default=0, help='hub TCP port on 127.0.0.1 (0: free)')
    ap.add_argument('--port-file', default='', help='write the hub address to this file')
    ap.add_argument('--node-id', type=int, action='append', help='drive node id (repeatable)')
    ap.add_argument('--eds', default='', help="the drive's EDS (default: the simulated one)")
    ap.add_argument('--sync-period', type=float, default=limits.SAMPLE_TIME_S)
    ap.add_argument('--working-condition', default='deep_sea', choices=('deep_sea', 'lab'))
    ap.add_argument('--torque-time-constant', type=float, default=2.0e-4)
    ap.add_argument('--initial-position', type=float, default=0.0, help='joint angle [rad]')
    ap.add_argument(
        '--encoder-offset-counts',
        type=int,
        default=0,
        help='position actual at angle 0 (an absolute encoder offset)',
    )
    ap.add_argument('--polarity', type=int, default=0, help='0x607E as set in the drive tool')
    ap.add_argument('--counts-per-rev', type=int, default=4096)
    ap.add_argument('--gear-ratio', type=float, default=limits.NOMINAL_GEAR_RATIO)
    ap.add_argument('--rated-torque', type=float, default=RATED_TORQUE_NM)
    ap.add_argument('--rated-current', type=float, default=RATED_CURRENT_A)
    ap.add_argument('--torque-constant', type=float, default=limits.NOMINAL_TORQUE_CONSTANT_NM_A)
    ap.add_argument('--over-current', type=float, default=1.25 * limits.CURRENT_LIMIT_A)
    ap.add_argument('--fault-kind', default='none', choices=('none', *FAULT_CODES))
    ap.add_argument('--fault-at', type=float, default=-1.0)
    ap.add_argument('--emcy-code', type=int, default=0xFF00)
    ap.add_argument('--emcy-at', type=float, default=-1.0)
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--silent-at', type=float, default=-1.0)
    ap.add_argument('--drop-tpdo', type=float, default=0.0)
    ap.add_argument('--late-tpdo', type=float, default=0.0)
    ap.add_argument('--no-load', action='store_true', help='not: ' + _described('load'))
    ap.add_argument('--emcy-register', type=int, default=0, help=_described('emcy_register'))
    ap.add_argument('--transition-16', action='store_true', help=_described('transition_16'))
    ap.add_argument(
        '--no-halted-bit', action='store_true', help='not: ' + _described('halted_bit')
    )
    ap.add_argument(
        '--velocity-quick-stop', action='store_true', help=_described('velocity_quick_stop')
    )
    ap.add_argument('--produces-sync', action='store_true', help=_described('produces_sync'))
    ap.add_argument(
        '--fixed-mapping-entry',
        type=_mapping_entry,
        default=None,
        help=_described('fixed_mapping_entry'),
    )
    ap.add_argument(
        '--encoder-sign', type=int, choices=(1, -1), default=1, help=_described('encoder_sign')
    )
    ap.add_argument(
        '--inject',
        type=_injection,
        action='append',
        default=[],
        help=f'KIND@T_S, KIND one of {", ".join(INJECTIONS)}',
    )
    ap.add_argument(
        '--thread-priority',
        type=_priority,
        default=0,
        metavar='0-99',
        help='SCHED_FIFO priority of every thread (0 = normal): the drive is hardware, it keeps '
        'its cycle whatever the master and the nodes under test do',
    )
    ap.add_argument(
        '--left-enabled',
        type=int,
        default=None,
        metavar='PERMILLE',
        help='start operational and enabled with this 0x6071 (a crashed master)',
    )
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Run the hub and the drives until SIGINT or SIGTERM."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if '--ros-args' in argv:  # started as a launch Node: the ROS arguments are not ours
        argv = argv[: argv.index('--ros-args')]
    args = parser().parse_args(argv)
    faulthandler.register(signal.SIGUSR1, all_threads=True)  # kill -USR1: every thread's stack
    ids = args.node_id or [1]
    scaling = Scaling(
        args.counts_per_rev,
        args.gear_ratio,
        args.rated_torque,
        args.rated_current,
        args.torque_constant,
    )
    plan = FaultPlan(
        args.fault_kind,
        args.fault_at,
        args.emcy_code,
        args.emcy_at,
        args.drop_tpdo,
        args.silent_at,
        args.seed,
        tuple(args.inject),
        late_tpdo_fraction=args.late_tpdo,
        emcy_register=args.emcy_register,
    )
    quirks = Quirks(
        transition_16=args.transition_16,
        halted_bit=not args.no_halted_bit,
        velocity_quick_stop=args.velocity_quick_stop,
        sync_producer=args.produces_sync,
        fixed_mapping_entry=args.fixed_mapping_entry,
        encoder_sign=args.encoder_sign,
    )
    if args.thread_priority:  # before any thread exists: every thread inherits it
        refused = RealtimeSettings(thread_priority=args.thread_priority).apply()
        print(refused or f'running under SCHED_FIFO priority {args.thread_priority}', flush=True)
    hub = Hub(args.port).start()
    print(f'bus hub on {hub.address}', flush=True)
    if args.port_file:
        with open(args.port_file, 'w') as f:
            f.write(hub.address)

    def on_event(text: str) -> None:
        print(text, flush=True)
        for kind in ('bus_off', 'error_passive'):
            if text.endswith(f'injected: {kind}'):
                hub.broadcast(error_frame(kind))

    drives, networks = [], []
    for node_id in ids:
        network = canopen.Network(hub.attach())
        network.NOTIFIER_CYCLE = 0.1
        network.connect()
        drive = SimulatedDrive(
            args.eds or default_eds(),
            node_id,
            scaling,
            args.sync_period,
            plant_parameters(args.working_condition, load=not args.no_load),
            args.torque_time_constant,
            plan,
            args.over_current,
            args.initial_position,
            args.encoder_offset_counts,
            on_event,
            quirks,
        )
        drive.save(0x607E, 0, bytes([args.polarity & 0xFF]))  # set in the drive tool
        drive.attach(network)
        if args.left_enabled is not None:
            drive.leave_enabled(args.left_enabled)
        drives.append(drive)
        networks.append(network)
        print(f'drive {node_id} ready', flush=True)
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    done.wait()
    for drive in drives:
        drive.stop()
        print(
            f'drive {drive.node.id}: SYNCs {drive.sync_frames} '
            f'({drive.clock.counted_syncs} with a counter), RPDOs discarded '
            f'{drive.rpdos_discarded}, TPDOs dropped {drive.tpdos_dropped}, late '
            f'{drive.tpdos_late}',
            flush=True,
        )
    for network in networks:
        network.disconnect()
    hub.stop()
    bits = sum(frame_bits(dlc) * n for dlc, n in enumerate(hub.dlc_counts))
    print(f'hub relayed {hub.frames} frames, {bits} bits worst case', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
