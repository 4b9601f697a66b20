# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What ``bag_identify`` reads from a bag: the angle and the current the joint held, per sample.

The angle is joint_states' position (the joint named ``joint_name``, else the first). The
current held over the interval before each sample, from the best source the bag has:
  1. ``plant/truth`` current_a: the simulated joint's applied current (exact);
  2. joint_states effort / ``torque_per_amp``: the torque the joint reports at its shaft divided
     by the k_t N it was computed with (the CiA 402 driver's effort is the drive's torque actual,
     k_t N times the current it measured: give its torque_constant_nm_a x gear_ratio); only with
     ``torque_per_amp`` given, as the bag does not say which k_t the joint used (the simulated
     plant reports k_t N with its own, true k_t);
  3. ``current_command`` one sample earlier: a drive applies the command answering sample k-1
     over the interval before sample k (``COMMAND_LAG_SAMPLES``); where the drive's gate held
     another current (a late command, a timeout) this is wrong, and the tool says so.
Samples that cannot serve are left out and split the run into records: joint samples missing
(a gap in the stamps), the brake engaged (plant/truth), the controller not controlling
(controller/state status other than OK or RECOVERING), a stamp with no current. A sample is at
the current limit when controller/state says the command before it was saturated (without
controller/state: when |i| reaches ``current_limit_a``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import numpy as np

from actuator_bag.errors import AnalysisError
from actuator_bag.msgdefs import DefinitionSource
from actuator_bag.reading import bag_typestore, find_topic, open_bag, topic_names
from actuator_core import limits
from actuator_core.status import CONTROLLED
from actuator_core.timing import stamp_to_ns

from .analyze import CONTROLLER_STATE, CURRENT_COMMAND, JOINT_STATE, PLANT_TRUTH
from .identify import Record

#: Samples between a command's stamp and the end of the interval it is held over.
COMMAND_LAG_SAMPLES = 1
#: A stamp step further than this share of a period from the period is a gap.
GAP_TOLERANCE = 0.5
#: Current sources, best first.
SOURCES = ('plant/truth current_a', 'joint_states effort / torque_per_amp', 'current_command')


@dataclass
class BagSamples:
    """The per-sample columns of one bag, on the joint's stamps."""

    path: Path
    stamps_ns: np.ndarray
    position_rad: np.ndarray
    current_a: np.ndarray  # held over the interval before each sample; NaN where unknown
    usable: np.ndarray  # bool: controlled, brake off
    at_limit: np.ndarray
    source: str
    notes: list[str] = field(default_factory=list)


def _rows(path: Path, source: Optional[DefinitionSource], joint_name: str) -> dict[str, list]:
    """Read the four topics' fields (stamp first) from one bag."""
    with open_bag(path) as reader:
        conns = reader.connections
        wanted = {
            'joint': find_topic(conns, JOINT_STATE, 'joint_states'),
            'truth': find_topic(conns, PLANT_TRUTH, 'plant/truth'),
            'state': find_topic(conns, CONTROLLER_STATE, 'controller/state'),
            'command': find_topic(conns, CURRENT_COMMAND, 'current_command'),
        }
        if wanted['joint'] is None:
            raise AnalysisError(
                f'{path}: no {JOINT_STATE} topic (joint_states) to identify from; the bag has: '
                f'{topic_names(conns)}'
            )
        present = {k: c for k, c in wanted.items() if c is not None}
        by_id = {c.id: k for k, c in present.items()}
        store = bag_typestore(reader, source, list(present.values()))
        rows: dict[str, list] = {k: [] for k in present}
        for conn, _, raw in reader.messages(connections=list(present.values())):
            kind = by_id[conn.id]
            try:
                msg = store.deserialize_cdr(raw, conn.msgtype)
            except Exception as err:  # noqa: BLE001 - any decode failure is a bad bag
                raise AnalysisError(f'{path}: a {conn.topic} message does not decode ({err})')
            row = _extract(kind, msg, joint_name)
            if row is not None:
                rows[kind].append(row)
    return rows


def _extract(kind: str, msg: Any, joint_name: str) -> Optional[tuple]:
    """(stamp, fields...) of one message; None for a joint_states without the joint."""
    stamp = stamp_to_ns(msg.header.stamp)
    if kind == 'joint':
        names = list(msg.name)
        index = names.index(joint_name) if joint_name in names else (0 if not joint_name else -1)
        if index < 0 or index >= len(msg.position):
            return None
        effort = float(msg.effort[index]) if index < len(msg.effort) else float('nan')
        return stamp, float(msg.position[index]), effort
    if kind == 'truth':
        return stamp, float(msg.current_a), bool(msg.brake_engaged)
    if kind == 'state':
        return stamp, int(msg.status), bool(msg.saturated)
    return stamp, float(msg.current_a)


def _on(stamps: np.ndarray, rows: list[tuple], column: int) -> tuple[np.ndarray, np.ndarray]:
    """Column ``column`` of ``rows`` at ``stamps`` (their stamp first), and where it is present."""
    table = {r[0]: r[column] for r in rows}
    present = np.array([int(s) in table for s in stamps], dtype=bool)
    values = np.array([float(table.get(int(s), 0.0)) for s in stamps])
    return values, present


def load_bag(
    path: os.PathLike | str,
    source: Optional[DefinitionSource] = None,
    joint_name: str = '',
    torque_per_amp: Optional[float] = None,
    current_limit_a: float = limits.CURRENT_LIMIT_A,
) -> BagSamples:
    """Read the samples of one bag with the best current source it has (module docstring)."""
    path = Path(path)
    rows = _rows(path, source, joint_name)
    joint = sorted({r[0]: r for r in rows['joint']}.values())
    if len(joint) < 2:
        named = f' named {joint_name!r}' if joint_name else ''
        raise AnalysisError(f'{path}: joint_states has {len(joint)} samples of a joint{named}')
    stamps = np.array([r[0] for r in joint], dtype=np.int64)
    position = np.array([r[1] for r in joint], dtype=float)
    effort = np.array([r[2] for r in joint], dtype=float)
    notes: list[str] = []
    usable = np.ones(len(stamps), dtype=bool)
    if rows.get('truth'):
        current, present = _on(stamps, rows['truth'], 1)
        brake, _ = _on(stamps, rows['truth'], 2)
        usable &= present & (brake == 0.0)
        chosen = SOURCES[0]
    elif torque_per_amp is not None and np.any(np.isfinite(effort)):
        current = effort / torque_per_amp
        chosen = SOURCES[1]
    elif rows.get('command'):
        commanded, present = _on(stamps, rows['command'], 1)
        lag = COMMAND_LAG_SAMPLES
        current = np.concatenate((np.zeros(lag), commanded[:-lag]))
        usable &= np.concatenate((np.zeros(lag, dtype=bool), present[:-lag]))
        chosen = SOURCES[2]
        notes.append(
            'the current is the one commanded a sample earlier (the bag has neither plant/truth '
            'nor, with --torque-per-amp, an effort): wherever the drive held another current '
            '(late commands, timeouts) the fit is wrong there'
        )
    else:
        raise AnalysisError(
            f'{path}: no current to identify from: the bag has no plant/truth, no '
            'current_command, and joint_states effort needs --torque-per-amp'
        )
    if rows.get('state'):
        status, present = _on(stamps, rows['state'], 1)
        usable &= present & np.isin(status, [int(s) for s in CONTROLLED])
        saturated = _on(stamps, rows['state'], 2)[0] != 0.0
        at_limit = np.concatenate(([False], saturated[:-1]))  # the command held before sample k
    else:
        at_limit = np.abs(current) >= current_limit_a
    return BagSamples(path, stamps, position, current, usable, at_limit, chosen, notes)


def sample_period_ns(stamps_ns: np.ndarray) -> int:
    """Return the joint's sample period: the median stamp step [ns]."""
    return int(np.median(np.diff(stamps_ns)))


def split_records(samples: BagSamples, period_ns: Optional[int] = None) -> list[Record]:
    """Contiguous runs of usable samples on the period's grid, each a Record."""
    period = sample_period_ns(samples.stamps_ns) if period_ns is None else period_ns
    if period <= 0:
        raise AnalysisError(f'{samples.path}: joint_states stamps do not advance')
    step = np.diff(samples.stamps_ns)
    on_grid = np.abs(step - period) <= GAP_TOLERANCE * period
    keep = samples.usable.copy()
    breaks = np.flatnonzero(~on_grid) + 1  # a record ends before each gap
    records = []
    for part in np.split(np.arange(len(keep)), breaks):
        runs = np.split(part, np.flatnonzero(~keep[part]))
        for run in runs:
            run = run[keep[run]]
            if run.size >= 2:
                start_s = (samples.stamps_ns[run[0]] - samples.stamps_ns[0]) * 1e-9
                records.append(
                    Record(
                        period * 1e-9,
                        samples.position_rad[run],
                        samples.current_a[run],
                        samples.at_limit[run],
                        f'{samples.path.name}@{start_s:.3f}s',
                    )
                )
    return records
