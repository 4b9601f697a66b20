# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What the CiA 402 master watches besides the cycle's samples, ROS-free.

``torque_fault``   every statusword that means the drive does not apply the commanded torque;
``stopped``        whether a statusword shows a drive that has ended its stop;
``PositionUnwrap`` the INTEGER32 position actual unwrapped;
``BusHealth``      error frames and a vanished adapter (and whether frames can still be sent);
``DriveHeartbeat`` the drive's own heartbeat (0x1017) consumed: a boot-up after configure
                   (a reboot: the configuration is lost) and silence.
"""

from __future__ import annotations

from typing import Optional

import can

from actuator_cia402 import profile as p
from actuator_cia402.hub import bus_error

ALLOWED_WHILE_RUNNING = (p.State.SWITCHED_ON, p.State.OPERATION_ENABLED)
#: States in which the drive's own stop reaction is still under way (or may be: quick stop
#: active under an option code that stays there).
STOPPING_STATES = (
    p.State.OPERATION_ENABLED,
    p.State.QUICK_STOP_ACTIVE,
    p.State.FAULT_REACTION_ACTIVE,
)
#: States with the power stage off (voltage disabled or in fault): the end of every stop.
DISABLED_STATES = (p.State.SWITCH_ON_DISABLED, p.State.NOT_READY_TO_SWITCH_ON, p.State.FAULT)
#: Drive heartbeat periods without one before the drive counts as silent.
HEARTBEAT_PERIODS_MISSED = 3


def torque_fault(statusword: int, enable_settled: bool) -> str:
    """Why a drive with this statusword does not apply the commanded torque ('' when it does).

    ``enable_settled``: operation enabled was commanded long enough ago to be shown.
    """
    state = p.decode_state(statusword)
    if state in (p.State.FAULT, p.State.FAULT_REACTION_ACTIVE):
        return f'drive fault ({state.value}, statusword 0x{statusword:04X})'
    if not statusword & p.SW_REMOTE:
        return 'remote off: the drive is under local control (statusword bit 9 low)'
    if state is p.State.QUICK_STOP_ACTIVE:
        return 'quick stop active: a quick-stop input or the drive stopped by itself'
    if state not in ALLOWED_WHILE_RUNNING or not statusword & p.SW_VOLTAGE_ENABLED:
        return (
            f'operation left without a fault: {state.value if state else "undefined"}, '
            f'voltage {"on" if statusword & p.SW_VOLTAGE_ENABLED else "off"} (STO, enable '
            'input or DC link lost?)'
        )
    if enable_settled:
        if state is not p.State.OPERATION_ENABLED:
            return f'operation not enabled ({state.value}) although commanded (STO?)'
        if not statusword & p.SW_FOLLOWS_TARGET:
            return 'the drive ignores the target torque (statusword bit 12 low)'
    return ''


def stopped(statusword: int) -> bool:
    """Whether the drive has ended its stop: a known state without a stop reaction under way.

    In each of those states the drive function is disabled (no torque), whatever its current
    measurement reads; never from bit 10 (not defined for CST on real drives).
    """
    state = p.decode_state(statusword)
    return state is not None and state not in STOPPING_STATES


def describe(statusword: int, current_a: float, brake_closed: Optional[bool]) -> str:
    """One line on what the drive shows: state, statusword, current actual, brake."""
    state = p.decode_state(statusword)
    brake = {True: 'closed', False: 'open', None: 'not reported'}[brake_closed]
    return (
        f"drive '{state.value if state else 'undefined'}' (statusword 0x{statusword:04X}), "
        f'current actual {current_a:.2f} A, brake {brake}'
    )


class PositionUnwrap:
    """Unwraps the INTEGER32 position actual into an unbounded count."""

    def __init__(self) -> None:
        """No reading yet."""
        self.last: Optional[int] = None
        self.total = 0
        self.wraps = 0

    def update(self, raw: int) -> int:
        """Add the shortest step from the last reading (mod 2^32); return the unwrapped count."""
        if self.last is None:
            self.total = raw
        else:
            step = (raw - self.last + 2**31) % 2**32 - 2**31
            if raw - self.last != step:
                self.wraps += 1
            self.total += step
        self.last = raw
        return self.total


class BusHealth(can.Listener):
    """Error frames and receive failures of the adapter, as one message.

    ``can_send`` is False once nothing can reach the drive (bus-off, adapter lost); an
    error-passive controller still sends, so the drive can still be stopped over the bus.
    """

    def __init__(self) -> None:
        """Start with a healthy bus."""
        self.fault = ''
        self.can_send = True

    def on_message_received(self, msg: can.Message) -> None:
        """Take an error frame (SocketCAN's coding, as the hub sends it)."""
        text = bus_error(msg)
        if text and not self.fault:
            self.fault = f'{text}: control ended'
        if text and 'bus-off' in text:
            self.can_send = False

    def on_error(self, exc: Exception) -> None:
        """Take a failing adapter: nothing can be sent any more."""
        self.can_send = False
        if not self.fault:
            self.fault = f'CAN adapter lost ({exc}): control ended'


class DriveHeartbeat:
    """The drive's heartbeat as this master consumes it: boot-ups and silence."""

    def __init__(self, period_s: float, now_s: float) -> None:
        """Watch a heartbeat of ``period_s``, from ``now_s`` (monotonic) on."""
        self.timeout_s = HEARTBEAT_PERIODS_MISSED * period_s
        self.since_s = now_s
        self.last_s: Optional[float] = None
        self.boots = 0

    def on_heartbeat(self, state: int, now_s: float) -> None:
        """Take one heartbeat frame of the drive (NMT state 0: its boot-up)."""
        if state == 0:
            self.boots += 1
        self.last_s = now_s

    def problem(self, now_s: float) -> str:
        """Return why the drive cannot be trusted as configured ('' when it can)."""
        if self.boots:
            return (
                f'the drive rebooted (boot-up seen {self.boots}x since configure): its '
                'configuration (0x1016, 0x6007, limits, PDO mapping) is lost; configure again'
            )
        silent_s = now_s - max(self.since_s, self.last_s or self.since_s)
        if silent_s > self.timeout_s:
            return (
                f'no heartbeat from the drive for {silent_s:.2f} s (its 0x1017 period is '
                f'{self.timeout_s / HEARTBEAT_PERIODS_MISSED * 1000:.0f} ms): powered off or '
                'disconnected?'
            )
        return ''
