# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The first-power-on sign check: a small current must move the joint its own way. ROS-free.

A positive current must turn the joint positive (polarity 0x607E, motor phases and encoder
direction all agree), or the closed loop runs with positive feedback. ``SignCheck.update`` takes
each sample of the first ``window_s`` at the test current and says, as soon as it can: the
sign is right (moved at least ``min_travel_rad`` the current's way), wrong (moved that far the
other way), or unknown (did not move that far within the window: a blocked joint, the brake,
too little current). Anything but 'right' is a refusal, in one line.
"""

from __future__ import annotations

import math
from typing import Optional

#: Joint travel that counts as a move [rad]: 20 encoder counts of 4096 x 100 and well above
#: the encoder's noise.
MIN_TRAVEL_RAD = 3.0e-4
#: How long the test current may take to move the joint that far [s].
WINDOW_S = 0.5


class SignCheck:
    """Judges the joint's first move under ``current_a`` (nonzero) against the current's sign."""

    def __init__(
        self, current_a: float, min_travel_rad: float = MIN_TRAVEL_RAD, window_s: float = WINDOW_S
    ) -> None:
        """Expect the joint to move ``min_travel_rad`` the way of ``current_a`` in ``window_s``."""
        if not (math.isfinite(current_a) and current_a != 0.0):
            raise ValueError(f'the sign check needs a nonzero current, got {current_a}')
        self.current_a = current_a
        self.min_travel_rad, self.window_s = min_travel_rad, window_s
        self.start_rad: Optional[float] = None
        self.verdict = ''  # '' while undecided, then 'right' or the refusal

    def update(self, elapsed_s: float, position_rad: float) -> str:
        """Take a sample ``elapsed_s`` after the current was applied; return the verdict so far."""
        if self.verdict:
            return self.verdict
        if self.start_rad is None:
            self.start_rad = position_rad
            return ''
        travel = position_rad - self.start_rad
        way = math.copysign(1.0, self.current_a)
        if travel * way >= self.min_travel_rad:
            self.verdict = 'right'
        elif -travel * way >= self.min_travel_rad:
            self.verdict = (
                f'sign check failed: {self.current_a:+g} A moved the joint {travel:+.5f} rad, '
                'the other way: polarity 0x607E, the motor phases or the encoder direction is '
                'wrong, or a load outweighs the current (free the joint); stopped'
            )
        elif elapsed_s >= self.window_s:
            self.verdict = (
                f'sign check failed: {self.current_a:+g} A moved the joint {travel:+.5f} rad in '
                f'{elapsed_s:.2f} s (less than {self.min_travel_rad:g} rad): free the joint or '
                'raise --current; stopped'
            )
        return self.verdict

    def line(self) -> str:
        """One line on a passed check, for the tool's output."""
        return f'sign check: {self.current_a:+g} A moved the joint its way: the sign is right'
