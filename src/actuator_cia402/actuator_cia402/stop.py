# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""How a ``Cia402Joint`` ends control: a mixin with end_control, deactivate, cleanup, close.

A synchronous drive takes the RPDO only at a SYNC, so a write after the last cycle never
reaches it. Whatever ended control (the node's soft limits or stale loop, the drive's
statusword, an EMCY, error-passive, a reboot, a second SYNC producer, deactivate), the drive
is stopped the same way:

1. braked cycles: RPDO 'switched on + halt' with 0 A (disable operation, 0x605C = 1), then
   the SYNC (or the bus's) and the TPDOs, each period on the monotonic clock, until the drive
   shows it stopped (``supervision.stopped``: no stop reaction under way, read from the
   statusword's state);
   the drive takes 0 A at the first SYNC, or at the second when the first RPDO came later
   than the SYNC window after the last SYNC (0x1007 discards it): every later braked RPDO
   goes out right after a SYNC, deep inside its window;
2. the stop over SDO (``Cia402Master.stop``) at once when those cycles could not stop it
   (no answer for ``feedback_timeout_s``, e.g. a SYNC consumer whose producer is gone, or
   not stopped within ``state_timeout_s``), else at deactivate: disable voltage whatever
   failed before, NMT stop for a drive that keeps its voltage;
3. NMT pre-operational for a drive seen disabled; otherwise this master's heartbeat falls
   silent, so the drive's heartbeat consumer (0x1016) stops it, and cleanup leaves 0x1016
   armed. With bus-off or a lost adapter nothing reaches the drive: only (3).

Every line it returns or keeps says what the drive did, read from its statusword (TPDO1 in
the cycles, SDO after them), never what was written.
"""

from __future__ import annotations

import math
import threading
import time
from typing import TYPE_CHECKING, Callable, Optional

import can
import canopen

from actuator_cia402 import profile as p
from actuator_cia402.master import Cia402Error, Cia402Master
from actuator_cia402.supervision import DISABLED_STATES, BusHealth, describe, stopped

if TYPE_CHECKING:
    from actuator_cia402.config import DriverParameters
    from actuator_cia402.scaling import Scaling
    from actuator_core.joint import JointSample

SDO_ERRORS = (Cia402Error, canopen.SdoAbortedError, canopen.SdoCommunicationError, can.CanError)


class Cia402Stop:
    """The end of control of ``Cia402Joint``: braked cycles, the stop over SDO, the watchdog."""

    # What Cia402Joint holds (set in its __init__, configure and cycle) and this part uses.
    cfg: DriverParameters
    scaling: Scaling
    period_ns: int
    wait_s: float
    network: Optional[canopen.Network]
    master: Optional[Cia402Master]
    health: BusHealth
    active: bool
    statusword: int
    _tpdo1_seq: int
    _tpdo2: tuple[int, int, int]  # current actual, error code, mode display (TPDO2)
    _tpdo2_seq: int
    _last_stamp_ns: int
    _no_enable: bool
    _heartbeat_stop: threading.Event
    _heartbeat: Optional[threading.Thread]

    if TYPE_CHECKING:  # Cia402Joint's cycle

        def write(self, current_a: float, brake: bool) -> None: ...

        def read(self, stamp_ns: int) -> Optional[JointSample]: ...

        def _wait(self, condition: Callable[[], bool], timeout_s: float) -> bool: ...

    def init_stop(self) -> None:
        """Nothing stopped yet (configure, activate)."""
        self.stop_report = ''  # what the drive did when control ended (the node logs it)
        self._stop_notes: list[str] = []  # warnings of a stop over SDO made in end_control
        self.silenced = False  # the master heartbeat is off: a stop failed, 0x1016 must act
        # the brake's 'closed' as last read over SDO (None: unknown)
        self.brake_seen: Optional[bool] = None

    @property
    def _configured(self) -> Cia402Master:
        """The master of the configured joint (``configure`` made it, ``cleanup`` drops it)."""
        assert self.master is not None, 'the joint is not configured'
        return self.master

    def end_control(self, reason: str) -> str:
        """Stop the drive now that control ended (``reason``); return (and keep) what it did."""
        self._no_enable = True
        self.stop_report = self._stop_now()
        return self.stop_report

    def describe(self) -> str:
        """One line: the drive as last read (state, statusword, current actual, brake)."""
        current = self.scaling.permille_to_current(self._tpdo2[0])
        return describe(self.statusword, current, self.brake_seen)

    def stop_refusal(self) -> str:
        """Why the joint may not be activated after its last stop ('' when it may)."""
        if self.silenced:
            return (
                'the last stop left the drive with its voltage (see the deactivate warning): '
                'cleanup and configure again'
            )
        return ''

    def _stop_now(self) -> str:
        """Braked cycles, else the stop over SDO at once; return what the drive did."""
        if self.master is None:
            return ''
        if not self.health.can_send:
            self._silence()
            return (
                f'{self.health.fault}: nothing reaches the drive; its heartbeat consumer stops '
                f'it after {self.cfg.heartbeat_timeout_s:g} s without this master'
            )
        first_zero, cycles = self._brake_cycles()
        zero = f'0 A after {first_zero} braked cycle(s), ' if first_zero else ''
        if cycles:
            self._refresh()
            return f'{zero}stopped after {cycles}: {self.describe()}'
        self._sdo_stop()
        return f'{zero}braked cycles did not stop it; over SDO: {self.describe()}'

    def _brake_cycles(self) -> tuple[int, int]:
        """Cycles with the gate closed until the drive has stopped.

        Return (the cycle whose answer first showed 0 A, the cycle it showed stopped); 0 for
        either that did not come within ``state_timeout_s``, or before the drive had answered
        no cycle for ``feedback_timeout_s`` (the cycle's own rule for a silent drive).
        """
        period_s = self.cfg.sync_period_s
        unanswered_max = max(1, math.ceil(self.cfg.feedback_timeout_s / period_s))
        start = time.monotonic()
        unanswered = first_zero = 0
        self.write(0.0, True)  # the next SYNC takes it, unless it is past the SYNC window
        for n in range(1, math.ceil(self.cfg.state_timeout_s / period_s) + 1):
            before = self._tpdo1_seq
            self.read(self._last_stamp_ns + self.period_ns)
            # right after the SYNC, deep inside its window 0x1007: the next SYNC takes it
            self.write(0.0, True)
            if not self.health.can_send:
                return first_zero, 0
            if self._tpdo1_seq == before:
                unanswered += 1
                if unanswered >= unanswered_max:
                    return first_zero, 0
            else:
                unanswered = 0
                self._wait(lambda: self._tpdo2_seq >= self._tpdo1_seq, self.wait_s)
                if not first_zero and self._tpdo2[0] == 0:
                    first_zero = n
                if stopped(self.statusword):
                    return first_zero, n
            time.sleep(max(0.0, start + n * period_s - time.monotonic()))
        return first_zero, 0

    def _sdo_stop(self) -> None:
        """Stop over SDO (quick stop, disable voltage, else NMT stop); keep its warnings."""
        try:
            self._stop_notes += self._configured.stop()
        except SDO_ERRORS as exc:
            self._stop_notes.append(f'stop over SDO: {exc}')
        if not self._configured.disabled:
            self._silence()
        self._refresh()

    def _refresh(self) -> None:
        """Read the statusword, current actual, error code and brake over SDO (diagnostics)."""
        try:
            master = self._configured
            self.statusword, current, code = master.read_process()
            self._tpdo2 = (current, code, self._tpdo2[2])
            self.brake_seen = master.brake_closed()
        except SDO_ERRORS:
            self.brake_seen = None

    def _silence(self) -> None:
        """Stop the master heartbeat: the drive's heartbeat consumer (0x1016) stops the drive."""
        self.silenced = True

    def deactivate(self) -> list[str]:
        """End control (braked cycles unless done), the stop over SDO, NMT pre-operational."""
        was_active, self.active = self.active, False
        if self.master is None:
            return []
        if was_active and not self.stop_report:
            self.stop_report = self._stop_now()
        notes, self._stop_notes = self._stop_notes, []
        if not self.health.can_send:
            return notes + [f'deactivate: {self.stop_report}']
        if not self.master.disabled and not self.silenced:  # a failed stop is not repeated
            self._sdo_stop()
            notes, self._stop_notes = notes + self._stop_notes, []
        if self.master.disabled:
            try:
                self.master.node.nmt.state = 'PRE-OPERATIONAL'
            except can.CanError as exc:
                notes.append(f'deactivate: NMT pre-operational: {exc}')
        return notes

    def cleanup(self) -> list[str]:
        """Heartbeat and bus down; 0x1016 cleared only for a drive seen disabled or in fault."""
        self.active = False
        self._heartbeat_stop.set()
        if self._heartbeat is not None:
            self._heartbeat.join(1.0)
        notes = []
        if self.master is not None and self.health.can_send:
            notes += self._release_watchdog()
        if self.network is not None:
            try:
                self.network.disconnect()
            except Exception:  # noqa: BLE001 - a vanished adapter: nothing left to close
                pass
        self.network = self.master = None
        return notes

    def _release_watchdog(self) -> list[str]:
        """Clear the drive's heartbeat consumer if it is disabled (the master leaves calmly)."""
        try:
            master = self._configured
            statusword, state = master.read_state()
            if state in DISABLED_STATES:
                master.node.sdo[p.HEARTBEAT_CONSUMER][1].raw = 0
                return []
            reason = f"drive '{state.value if state else 'undefined'}' (0x{statusword:04X})"
        except SDO_ERRORS as exc:
            reason = f'no answer ({exc})'
        return [
            f'heartbeat consumer 0x1016 left armed, {reason}: the drive stops itself '
            f'{self.cfg.heartbeat_timeout_s:g} s after this master'
        ]

    def close(self) -> list[str]:
        """At exit: stop the drive if it answers, then bus down; returns the warnings."""
        notes = self.deactivate() if self.active else []
        return notes + self.cleanup()
