# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""CAN bus load of one joint's cyclic traffic: SYNC plus the mapped PDOs, worst-case bit stuffing.

A classic CAN base frame (11-bit identifier) with n data bytes has 47 + 8 n bits: SOF 1,
identifier 11, RTR 1, IDE 1, r0 1, DLC 4, data 8 n, CRC 15, CRC delimiter 1, ACK 2, EOF 7,
intermission 3. Stuff bits are inserted after 5 equal bits in SOF..CRC (34 + 8 n bits); the
worst case is floor((34 + 8 n - 1) / 4). So a SYNC with its counter (1 byte, 0x1019) takes 65
bits (55 without), a 4-byte PDO 95, an 8-byte PDO 135.

This driver's cycle: SYNC with counter, RPDO1 (controlword + target torque, 4 bytes), TPDO1
(statusword + position actual + torque actual, 8 bytes), TPDO2 (current actual + error code +
mode display, 5 bytes): 400 bits per cycle. At 1 kHz that is 400 kbit/s: 40 % of 1 Mbit/s,
80 % of 500 kbit/s (one joint barely fits, no room for a second or for SDO traffic), 320 % of
125 kbit/s (refused). The master heartbeat (1 byte every 10 ms) adds 0.6 % at 1 Mbit/s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

#: Drives one bus may carry in this driver's layout (each its own node id and PDOs).
MAX_JOINTS_ON_BUS = 4
#: Refuse a configuration whose worst-case load exceeds this fraction of the bitrate.
DEFAULT_LIMIT = 0.8
#: Warn above this fraction.
DEFAULT_WARN = 0.6
#: Frame payloads [bytes] of the cycle: SYNC (its counter, the worst case), RPDO1, TPDO1, TPDO2.
CYCLE_PAYLOADS = (1, 4, 8, 5)


def frame_bits(data_bytes: int, worst_case_stuffing: bool = True) -> int:
    """Bits on the wire of a CAN 2.0A frame with ``data_bytes`` (0-8).

    incl. worst-case stuff bits.
    """
    if not 0 <= data_bytes <= 8:
        raise ValueError(f'a classic CAN frame carries 0-8 data bytes, got {data_bytes}')
    bits = 47 + 8 * data_bytes
    if worst_case_stuffing:
        bits += (34 + 8 * data_bytes - 1) // 4
    return bits


@dataclass(frozen=True)
class BusLoad:
    """Load of a cyclic frame set at a bitrate and cycle period."""

    bits_per_cycle: int
    cycle_period_s: float
    bitrate_bit_s: int

    @property
    def fraction(self) -> float:
        """Worst-case share of the bus used by the cycle (1.0 = saturated)."""
        return self.bits_per_cycle / (self.cycle_period_s * self.bitrate_bit_s)

    def text(self) -> str:
        """One line with the figure, e.g. '38.0 % of 1000 kbit/s (380 bits per 1 ms cycle)'."""
        return (
            f'{100.0 * self.fraction:.1f} % of {self.bitrate_bit_s / 1000:g} kbit/s '
            f'({self.bits_per_cycle} bits per {self.cycle_period_s * 1e3:g} ms cycle, '
            'worst-case stuffing)'
        )


def cycle_load(
    bitrate_bit_s: int,
    cycle_period_s: float,
    payloads: Sequence[int] = CYCLE_PAYLOADS,
    joints: int = 1,
) -> BusLoad:
    """Worst-case load of ``joints`` drives each sending ``payloads`` frames per cycle.

    One SYNC shared.
    """
    if bitrate_bit_s <= 0 or cycle_period_s <= 0:
        raise ValueError('bitrate and cycle period must be > 0')
    sync, *per_joint = payloads
    bits = frame_bits(sync) + joints * sum(frame_bits(n) for n in per_joint)
    return BusLoad(bits, cycle_period_s, int(bitrate_bit_s))


class BusLoadError(ValueError):
    """The cyclic traffic does not fit on the bus."""


def check_bus_load(
    bitrate_bit_s: int,
    cycle_period_s: float,
    payloads: Sequence[int] = CYCLE_PAYLOADS,
    limit: float = DEFAULT_LIMIT,
    warn: float = DEFAULT_WARN,
    joints: int = 1,
) -> str | None:
    """Raise BusLoadError (one line with the figure) above ``limit``.

    Return a warning text above ``warn``. ``joints``: drives sharing the bus and one SYNC.
    """
    load = cycle_load(bitrate_bit_s, cycle_period_s, payloads, joints)
    if load.fraction > limit:
        raise BusLoadError(
            f'bus load {load.text()}{_of(joints)} exceeds the limit of {100 * limit:g} %: '
            f'raise the bitrate or lengthen sync_period_s'
        )
    if load.fraction > warn:
        return (
            f'bus load {load.text()}{_of(joints)} is above {100 * warn:g} %: little room left '
            'for SDO, EMCY or another joint'
        )
    return None


def _of(joints: int) -> str:
    """' for 2 joints' when the load is of several joints, else ''."""
    return f' for {joints} joints' if joints > 1 else ''
