# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The simulated drive's CiA 402 power state machine and its stop reactions (a mixin).

``SimulatedDrive`` (sim_drive.py) holds the bus, the object dictionary and the cycle; this part
decides what its power stage does: the controlword transitions (and transition 16 where its
``Quirks`` allow it), the statusword, quick stop (0x605A), disable operation (0x605C) and the
fault reaction (0x605E) with their ramps, the holding brake's closing time (0x2100), the
heartbeat consumer (0x1016, 0x6007) and a reboot. A ramp takes the torque to 0 at the torque
slope 0x6087; a velocity-based quick stop (``Quirks.velocity_quick_stop``) decelerates the
motor at 0x6085 [rpm/s] with a velocity loop within the current limit instead.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

from actuator_cia402 import profile as p

if TYPE_CHECKING:
    import canopen

    from actuator_cia402.scaling import Scaling
    from actuator_cia402.sim_faults import Quirks
    from actuator_plant.sim_joint import SimulatedJoint

ERROR_REGISTER_GENERIC = 0x01
ERROR_REGISTER_CURRENT = 0x02
HEARTBEAT_ERROR = 0x8130
#: The states that need the power stage (none under STO).
POWERED_STATES = (p.State.READY_TO_SWITCH_ON, p.State.SWITCHED_ON, p.State.OPERATION_ENABLED)
#: Option codes of 0x605A that stay in 'quick stop active' (CiA 402: transition 16 possible).
STAYING_QUICK_STOP_OPTIONS = (5, 6, 7, 8)
#: Proportional gain of the drive's velocity loop in a velocity-based quick stop [A per rad/s
#: at the joint]: a time constant of about 6 ms with the deep-sea joint's 31 rad/s^2 per A.
STOP_VELOCITY_GAIN_A_S_RAD = 5.0


class DriveStateMachine:
    """The power state machine of ``SimulatedDrive``; reads its objects, moves its power stage."""

    # What SimulatedDrive holds (set in its __init__): read here, and the state moved here.
    scaling: Scaling
    dt_s: float
    joint: SimulatedJoint
    quirks: Quirks
    node: canopen.LocalNode
    state: p.State
    last_controlword: int
    target_permille: int
    error_code: int
    error_register: int
    brake_closed: bool
    _brake_closing_at: float | None
    ramp_permille: float
    _stopping: p.State | None
    _decelerating: bool
    _stop_velocity: float
    _cut_ramps: int
    sto: bool
    remote_off: bool
    target_ignored: bool
    silent: bool
    syncs: int
    _heartbeat_seen: float | None
    _heartbeat_lost: bool
    _heartbeat_producer: int

    if TYPE_CHECKING:  # SimulatedDrive's methods this part calls

        @property
        def _sign(self) -> int: ...

        def _cfg(self, index: int, subindex: int = 0) -> int: ...

        def _event(self, text: str) -> None: ...

        def _applied_target(self) -> int: ...

    @property
    def statusword(self) -> int:
        """Statusword 0x6041: state, remote, 'follows the target' in operation, bit 10 halted."""
        word = p.encode_statusword(self.state, remote=not self.remote_off)
        if self.sto:
            word &= ~p.SW_VOLTAGE_ENABLED
        if self.state is p.State.OPERATION_ENABLED and not self.target_ignored:
            word |= p.SW_FOLLOWS_TARGET
        halted = self.state is p.State.QUICK_STOP_ACTIVE and self._stopping is None
        if halted and self.quirks.halted_bit:
            word |= p.SW_TARGET_REACHED
        return word

    def apply_controlword(self, controlword: int) -> None:
        """One controlword 0x6040: CiA 402 transition; fault reset on the rising edge of bit 7.

        The transitions are profile.TRANSITIONS; this drive adds its guards (``_holds``) and
        the power stage's reactions (``_enter``).
        """
        if self.remote_off:
            return  # controlled locally: the bus's controlword is ignored
        command = p.decode_command(controlword)
        reset_bit = p.CW_FAULT_RESET
        rising = bool(controlword & reset_bit) and not self.last_controlword & reset_bit
        self.last_controlword = controlword
        if command is p.Command.FAULT_RESET:
            self._fault_reset(rising)
            return
        before = self.state
        if self._transition_16(before, command):
            return
        after = p.next_state(before, command)
        if not self._holds(before, after, command):
            self._enter(before, after)

    def _fault_reset(self, rising: bool) -> None:
        """Fault reset (transition 15): on the rising edge of bit 7, in 'fault' only."""
        if rising and self.state is p.State.FAULT:
            self.state, self.error_code, self.error_register = p.State.SWITCH_ON_DISABLED, 0, 0
            self._send_emcy(0x0000, 0)

    def _holds(self, before: p.State, after: p.State, command: p.Command) -> bool:
        """Whether the drive stays in ``before`` although the table leads to ``after``.

        No transition; a stop under way (only disable voltage cuts it); no power stage (STO)
        for a state that needs one; operation asked in a mode other than CST.
        """
        stopping = self._stopping is not None and command is not p.Command.DISABLE_VOLTAGE
        if after is before or stopping:
            return True
        if self.sto and after in POWERED_STATES:
            return True  # no power stage: stays in 'switch on disabled'
        enabling = after is p.State.OPERATION_ENABLED
        return enabling and self._cfg(p.MODES_OF_OPERATION) != p.MODE_CST  # CST only

    def _enter(self, before: p.State, after: p.State) -> None:
        """Do the power stage's part of a transition: the brake, a stop's ramp, the new state."""
        if after is p.State.OPERATION_ENABLED:
            self._event(f'operation enabled with 0x6071 = {self.target_permille} per mille')
            self.state, self.brake_closed, self._brake_closing_at = after, False, None
            self._event('brake released')
            return
        if before is p.State.OPERATION_ENABLED:
            if after is p.State.QUICK_STOP_ACTIVE:
                self.quick_stop()
                return
            if after is p.State.SWITCHED_ON and self._cfg(p.DISABLE_OPERATION_OPTION) == 1:
                self._begin_stop(1, after)
                return
            self._close_brake()
        if self._stopping is not None and after is p.State.SWITCH_ON_DISABLED:
            self._cut_ramp()
        elif after is p.State.SWITCH_ON_DISABLED and not self.brake_closed:
            self._event('voltage disabled with the brake open')
        self.state = after

    def _cut_ramp(self) -> None:
        """Disable voltage during a stop's ramp: it ends at once, the brake starts closing."""
        self._cut_ramps += 1
        self._event(
            f'ramp cut by disable voltage at {self.ramp_permille:.0f} per mille, '
            f'brake {"closed" if self.brake_closed else "open"}'
        )
        self._stopping = None
        self.ramp_permille, self._decelerating = 0.0, False
        self._close_brake()

    def _transition_16(self, before: p.State, command: p.Command) -> bool:
        """Transition 16 (quick stop active -> operation enabled), where the quirk allows it."""
        staying = self._cfg(p.QUICK_STOP_OPTION) in STAYING_QUICK_STOP_OPTIONS
        if not (
            self.quirks.transition_16
            and staying
            and before is p.State.QUICK_STOP_ACTIVE
            and command is p.Command.ENABLE_OPERATION
        ):
            return False
        self._stopping, self.ramp_permille, self._decelerating = None, 0.0, False
        self.state = p.State.OPERATION_ENABLED
        self.brake_closed, self._brake_closing_at = False, None
        self._event(
            f'transition 16: quick stop active -> operation enabled with 0x6071 = '
            f'{self.target_permille} per mille'
        )
        return True

    def quick_stop(self) -> None:
        """Quick stop from operation enabled (0x605A): the ramp or the deceleration, then final."""
        self._begin_stop(self._cfg(p.QUICK_STOP_OPTION), p.State.QUICK_STOP_ACTIVE)
        self.state = p.State.QUICK_STOP_ACTIVE
        if self.quirks.velocity_quick_stop:
            self._decelerating = True
            self._stop_velocity = self._joint_velocity()
            self._event(
                f'decelerating at 0x6085 = {self._cfg(p.QUICK_STOP_DECELERATION)} rpm/s from '
                f'{self._stop_velocity:.3f} rad/s'
            )

    def _begin_stop(self, option: int, final: p.State) -> None:
        """Ramp (option 1, 2, 5, 6) or not (0), then the brake, then ``final``."""
        self.ramp_permille = float(self._applied_target()) if option else 0.0
        stay = option in STAYING_QUICK_STOP_OPTIONS
        if final is p.State.QUICK_STOP_ACTIVE and not stay:
            final = p.State.SWITCH_ON_DISABLED
        self._stopping = final
        self._event(f'stopping: ramp from {self.ramp_permille:.0f} per mille (option {option})')

    def _close_brake(self) -> None:
        """Start closing the brake (closing time 0x2100)."""
        if not self.brake_closed and self._brake_closing_at is None:
            self._brake_closing_at = self.syncs * self.dt_s + self._cfg(p.BRAKE_CLOSING_MS) * 1e-3

    def _raise_fault(self, code: int) -> None:
        """Fault reaction (0x605E): ramp, brake, then 'fault'; 0x603F, 0x1001 set, EMCY sent."""
        powered = self.state in (p.State.OPERATION_ENABLED, p.State.QUICK_STOP_ACTIVE)
        self.error_code = code
        self.error_register = ERROR_REGISTER_GENERIC | (
            ERROR_REGISTER_CURRENT if code >> 12 == 0x2 else 0
        )
        self._send_emcy(code, self.error_register)
        self._event(f'fault 0x{code:04X} {p.error_text(code)}')
        if powered:
            self._decelerating = False
            self._begin_stop(2 if self._cfg(p.FAULT_REACTION_OPTION) else 0, p.State.FAULT)
            self.state = p.State.FAULT_REACTION_ACTIVE
        else:
            self.state = p.State.FAULT

    def _send_emcy(self, code: int, register: int) -> None:
        """EMCY frame (CiA 301: code, error register, 5 vendor bytes)."""
        if not self.silent:
            self.node.emcy.send(code, register)

    def _joint_velocity(self) -> float:
        """Joint velocity [rad/s] in the motor's sense (0x607E)."""
        return self._sign * float(self.joint.plant.velocity_rad_s)

    def _power_stage(self, t_s: float) -> float:
        """Return the motor current applied over this period [A]; ramps and brake advance."""
        s = self.scaling
        if self._brake_closing_at is not None and t_s >= self._brake_closing_at:
            self.brake_closed, self._brake_closing_at = True, None
            self._event('brake closed')
        if self._stopping is not None:
            if self._decelerating:
                current = self._decelerate()
            else:
                step = self._cfg(p.TORQUE_SLOPE) * self.dt_s
                r = self.ramp_permille
                self.ramp_permille = 0.0 if abs(r) <= step else r - step * (1 if r > 0 else -1)
                current = s.torque_permille_to_current(round(self.ramp_permille))
                if self.ramp_permille == 0.0:
                    self._close_brake()
            if self.brake_closed:
                self.state, self._stopping, self._decelerating = self._stopping, None, False
                self._event(f'stopped: {self.state.value}')
                return 0.0
            return current
        if self.state is p.State.OPERATION_ENABLED and not self.sto:
            if self.target_ignored or self.last_controlword & p.CW_HALT:
                return 0.0
            return s.torque_permille_to_current(self._applied_target())
        self._close_brake()
        return 0.0

    def _decelerate(self) -> float:
        """Velocity-based quick stop: follow a ramp to rest at 0x6085; the brake at its end."""
        s = self.scaling
        per_s2 = self._cfg(p.QUICK_STOP_DECELERATION) * 2.0 * math.pi / 60.0 / s.gear_ratio
        v_ref = self._stop_velocity
        step = per_s2 * self.dt_s
        self._stop_velocity = 0.0 if abs(v_ref) <= step else v_ref - math.copysign(step, v_ref)
        if self._stop_velocity == 0.0:
            self._close_brake()
        limit = s.permille_to_current(self._cfg(p.MAX_CURRENT))
        wanted = STOP_VELOCITY_GAIN_A_S_RAD * (self._stop_velocity - self._joint_velocity())
        return self._sign * max(-limit, min(limit, wanted))

    def _supervise_heartbeat(self) -> None:
        """Heartbeat consumer 0x1016: a producer silent beyond its time triggers 0x6007."""
        time_ms = self._cfg(p.HEARTBEAT_CONSUMER, 1) & 0xFFFF
        seen = self._heartbeat_seen
        if not time_ms or seen is None or self._heartbeat_lost:
            return
        if time.monotonic() - seen > time_ms * 1e-3:
            self._heartbeat_lost = True
            option = self._cfg(p.ABORT_CONNECTION_OPTION)
            self._event(
                f'heartbeat of node {self._heartbeat_producer} lost for {time_ms} ms: '
                f'abort connection option {option}'
            )
            self._send_emcy(HEARTBEAT_ERROR, ERROR_REGISTER_GENERIC)
            if option == 1:
                self._raise_fault(HEARTBEAT_ERROR)
            elif option == 2:
                self.apply_controlword(p.Command.DISABLE_VOLTAGE.value)
            elif option == 3:
                self.apply_controlword(p.Command.QUICK_STOP.value)
