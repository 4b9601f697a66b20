# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The drive's command gate: what current a drive (simulated joint or hardware driver) applies.

One object per drive, held by the plant node, the CiA 402 driver and the offline loop alike.
``offer`` checks each incoming ``current_command`` (finite, within the one current limit,
``safe_stop`` honoured); ``hold`` says what to apply over the sample that starts at a given
time: the newest accepted command, or 0 A with the holding brake engaged when the gate is not
active or when the command asked for a safe stop; 0 A once the newest command is older than
the timeout (a drive's command watchdog), and the brake too once it is older than the timeout
plus ``brake_delay_s`` (a short gap coasts at 0 A; the brake is for a lost controller or a
stopped joint). The brake is released again by the first valid command without ``safe_stop``
(ros2_control: "brakes released" on activation; here on the first command after it, so a
node that is not active never moves the joint). This is the one brake policy of every joint.

Currents and ``safe_stop`` may be numpy arrays (a batch of offline runs): refused or stopped
elements then get 0 A and the brake.
Times are integer nanoseconds of one clock chosen by the caller: the system clock in real
time, sim time (the sample stamps) in sim and offline.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Optional

import numpy as np

from actuator_core import limits
from actuator_core import xmath as xm


class Held(NamedTuple):
    """What the drive applies over one sample.

    Current [A], the stamp of its command, brake, reason.
    """

    current_a: float
    command_stamp_ns: int  # stamp of the command applied; -1 when none is
    brake: bool  # the holding brake is engaged
    reason: str  # '' while a command is applied, else why 0 A is


class CommandGate:
    """Command checks, hold over the sample, timeout and brake of one drive."""

    def __init__(
        self,
        current_limit_a: float = limits.CURRENT_LIMIT_A,
        timeout_s: float = limits.COMMAND_TIMEOUT_S,
        brake_delay_s: float = limits.BRAKE_DELAY_S,
    ):
        """Refuse currents beyond +-``current_limit_a``.

        0 A once commands are ``timeout_s`` old, the brake ``brake_delay_s`` later.
        """
        if not (math.isfinite(current_limit_a) and current_limit_a > 0.0):
            raise ValueError(f'current_limit_a must be finite and > 0, got {current_limit_a}')
        if not (math.isfinite(timeout_s) and timeout_s > 0.0):
            raise ValueError(f'timeout_s must be finite and > 0, got {timeout_s}')
        if not (math.isfinite(brake_delay_s) and brake_delay_s >= 0.0):
            raise ValueError(f'brake_delay_s must be finite and >= 0, got {brake_delay_s}')
        self.current_limit_a = current_limit_a
        self.timeout_ns = int(round(timeout_s * 1e9))
        self.brake_ns = self.timeout_ns + int(round(brake_delay_s * 1e9))
        self.active = False
        self.brake = True
        self._current_a = 0.0
        self._stamp_ns = -1
        self._received_ns: Optional[int] = None
        self._safe_stop = False
        self.refused = 0
        self.timeouts = 0
        self._timed_out = False

    def activate(self) -> None:
        """Start accepting commands; the brake stays engaged until the first valid command."""
        self.active = True
        self._received_ns = None
        self._current_a, self._stamp_ns, self._safe_stop = 0.0, -1, False

    def deactivate(self) -> None:
        """Stop: 0 A and the brake from now on, whatever arrives."""
        self.active = False
        self.brake = True
        self._current_a, self._stamp_ns = 0.0, -1

    def valid(self, current_a):
        """Whether a command may be applied: finite and within +-current_limit_a (elementwise)."""
        finite = xm.isfinite(current_a)
        return finite & (xm.fabs(xm.where(finite, current_a, 0.0)) <= self.current_limit_a)

    def offer(
        self, current_a: float, stamp_ns: int, safe_stop: bool, received_ns: int
    ) -> Optional[str]:
        """Take a command received at ``received_ns``.

        Returns None, or why it was refused (0 A then applies).
        """
        if not self.active:
            return 'the drive is not active'
        valid = self.valid(current_a)
        if not xm.all_true(valid):
            self.refused += 1
            if not isinstance(valid, np.ndarray):
                self._current_a, self._stamp_ns, self._safe_stop = 0.0, -1, True
                self._received_ns = received_ns
                self.brake = True
                return (
                    f'command {current_a} A refused (valid: finite, |u| <= '
                    f'{self.current_limit_a:g} A); applying 0 A'
                )
            current_a = xm.where(valid, current_a, 0.0)  # a batch: refused elements get 0 A
        self._received_ns = received_ns
        self._stamp_ns = stamp_ns
        if isinstance(safe_stop, np.ndarray):  # a batch: stopped elements get 0 A and the brake
            self._safe_stop = False
            self._current_a = xm.where(safe_stop, 0.0, current_a)
            self.brake = safe_stop if safe_stop.any() else False
            return None
        self._safe_stop = bool(safe_stop)
        self._current_a = 0.0 if safe_stop else current_a
        self.brake = bool(safe_stop)
        return None

    def hold(self, now_ns: int) -> Held:
        """Return what to apply over the sample starting at ``now_ns``."""
        if not self.active:
            self.brake = True
            return Held(0.0, -1, True, 'inactive')
        if self._received_ns is None:
            return Held(0.0, -1, self.brake, 'no command yet')
        age_ns = now_ns - self._received_ns
        if age_ns > self.timeout_ns:
            if not self._timed_out:
                self.timeouts += 1
                self._timed_out = True
            if age_ns > self.brake_ns:
                self.brake = True
            return Held(0.0, -1, self.brake, 'command timeout')
        self._timed_out = False
        if self._safe_stop:
            return Held(0.0, self._stamp_ns, True, 'safe stop')
        return Held(self._current_a, self._stamp_ns, self.brake, '')
