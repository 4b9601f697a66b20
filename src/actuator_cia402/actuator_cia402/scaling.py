# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Unit conversion between CiA 402 process data and SI units (REP-103).

Position actual 0x6064 is in counts of the motor-side encoder; the joint turns once every
``gear_ratio`` motor turns: q [rad] = counts * 2 pi / (counts_per_rev * N).
Torques 0x6071 / 0x6077 are in per mille of the rated torque 0x6076, currents 0x6078 in per
mille of the rated current 0x6075; the motor torque is k_t * i (paper eq. (1), k_t u), so a
current command i [A] is the torque k_t i [N m] = 1000 k_t i / T_rated per mille.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

INT16_MAX = 32767
INT32_MAX = 2**31 - 1


@dataclass(frozen=True)
class Scaling:
    """Conversion constants of one drive and joint (all SI)."""

    encoder_counts_per_rev: int
    gear_ratio: float
    rated_torque_nm: float
    rated_current_a: float
    torque_constant_nm_a: float

    def __post_init__(self) -> None:
        """Refuse non-positive or non-finite constants."""
        for name in (
            'encoder_counts_per_rev',
            'gear_ratio',
            'rated_torque_nm',
            'rated_current_a',
            'torque_constant_nm_a',
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f'{name} must be finite and > 0, got {value}')

    @property
    def rad_per_count(self) -> float:
        """Joint angle of one encoder count [rad]: 2 pi / (counts_per_rev N)."""
        return 2.0 * math.pi / (self.encoder_counts_per_rev * self.gear_ratio)

    def counts_to_rad(self, counts: int) -> float:
        """Joint angle [rad] of position actual 0x6064 [counts]."""
        return counts * self.rad_per_count

    def rad_to_counts(self, position_rad: float) -> int:
        """Position actual 0x6064 [counts] of a joint angle [rad], rounded to the nearest count."""
        counts = int(round(position_rad / self.rad_per_count))
        if abs(counts) > INT32_MAX:
            raise OverflowError(f'{position_rad} rad is beyond the INTEGER32 range of 0x6064')
        return counts

    def current_to_torque_permille(self, current_a: float) -> int:
        """Target torque 0x6071 [per mille of 0x6076] for the motor current ``current_a``.

        1000 k_t i / T_rated.
        """
        value = int(round(1000.0 * self.torque_constant_nm_a * current_a / self.rated_torque_nm))
        return max(-INT16_MAX, min(INT16_MAX, value))

    def torque_permille_to_current(self, permille: int) -> float:
        """Motor current [A] of a torque 0x6071/0x6077 [per mille].

        Permille T_rated / (1000 k_t).
        """
        return permille * self.rated_torque_nm / (1000.0 * self.torque_constant_nm_a)

    def torque_permille_to_nm(self, permille: int) -> float:
        """Motor torque [N m] of a torque object [per mille of 0x6076]."""
        return permille * self.rated_torque_nm / 1000.0

    def current_to_permille(self, current_a: float) -> int:
        """Return the current actual 0x6078 of ``current_a``.

        In per mille of the rated current 0x6075.
        """
        value = int(round(1000.0 * current_a / self.rated_current_a))
        return max(-INT16_MAX, min(INT16_MAX, value))

    def permille_to_current(self, permille: int) -> float:
        """Motor current [A] of current actual 0x6078 [per mille of 0x6075]."""
        return permille * self.rated_current_a / 1000.0

    @property
    def current_resolution_a(self) -> float:
        """Current of one per mille of rated torque [A]: the command quantum of 0x6071."""
        return self.rated_torque_nm / (1000.0 * self.torque_constant_nm_a)
