# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""CiA 402 drive profile: object indices, the power state machine, statusword and controlword.

ROS-free. Object indices and bit patterns follow CiA 402 part 2 (device control, section
"state machine"); the driver (master.py) and the simulated drive (sim_drive.py) both use
these, so the two can never disagree on a bit.
"""

from __future__ import annotations

import enum

#: The largest SYNC counter overflow value (CiA 301, 0x1019): the counter runs 1..240.
SYNC_COUNTER_MAX = 240

# --- object dictionary indices (CiA 301 communication area, CiA 402 profile area) -----------
DEVICE_TYPE = 0x1000  # UNSIGNED32; low 16 bits = device profile number (402)
ERROR_REGISTER = 0x1001  # UNSIGNED8 (CiA 301)
SYNC_COB_ID = 0x1005  # UNSIGNED32: bits 0-10 COB-ID, bit 30 this node produces the SYNC
COMMUNICATION_CYCLE_US = 0x1006  # UNSIGNED32, SYNC period [us]
SYNC_WINDOW_US = 0x1007  # UNSIGNED32, synchronous window length [us]
SYNC_COUNTER_OVERFLOW = 0x1019  # UNSIGNED8: 0 SYNC without counter, 2-240 the counter's overflow
HEARTBEAT_CONSUMER = 0x1016  # ARRAY of UNSIGNED32: bits 16-23 producer node id, 0-15 time [ms]
HEARTBEAT_PRODUCER_MS = 0x1017  # UNSIGNED16
IDENTITY = 0x1018  # RECORD
BRAKE_CLOSING_MS = 0x2100  # UNSIGNED16 [ms], the simulated drive's (manufacturer-specific)
ABORT_CONNECTION_OPTION = 0x6007  # INTEGER16: 0 none, 1 fault, 2 disable voltage, 3 quick stop
ERROR_CODE = 0x603F  # UNSIGNED16, last error code (same codes as EMCY)
CONTROLWORD = 0x6040  # UNSIGNED16
STATUSWORD = 0x6041  # UNSIGNED16
QUICK_STOP_OPTION = 0x605A  # INTEGER16
DISABLE_OPERATION_OPTION = 0x605C  # INTEGER16: 0 disable at once, 1 ramp, then disable
FAULT_REACTION_OPTION = 0x605E  # INTEGER16: 0 disable at once, 2 quick-stop ramp
MODES_OF_OPERATION = 0x6060  # INTEGER8
MODES_OF_OPERATION_DISPLAY = 0x6061  # INTEGER8
POSITION_ACTUAL = 0x6064  # INTEGER32 [encoder counts]
TARGET_TORQUE = 0x6071  # INTEGER16 [per mille of rated torque 0x6076]
MAX_TORQUE = 0x6072  # UNSIGNED16 [per mille of rated torque]
MAX_CURRENT = 0x6073  # UNSIGNED16 [per mille of rated current]
RATED_CURRENT = 0x6075  # UNSIGNED32 [mA]
RATED_TORQUE = 0x6076  # UNSIGNED32 [mN m]
TORQUE_ACTUAL = 0x6077  # INTEGER16 [per mille of rated torque]
CURRENT_ACTUAL = 0x6078  # INTEGER16 [per mille of rated current]
POLARITY = 0x607E  # UNSIGNED8: bit 7 position, bit 6 velocity
MAX_MOTOR_SPEED = 0x6080  # UNSIGNED32 [rpm]
QUICK_STOP_DECELERATION = 0x6085  # UNSIGNED32 [acceleration unit; rpm/s on the simulated drive]
TORQUE_SLOPE = 0x6087  # UNSIGNED32 [per mille of rated torque per s]
ENCODER_RESOLUTION = 0x608F  # ARRAY: 1 = encoder increments, 2 = motor revolutions
GEAR_RATIO = 0x6091  # ARRAY: 1 = motor revolutions, 2 = shaft revolutions
FEED_CONSTANT = 0x6092  # ARRAY: 1 = feed, 2 = shaft revolutions
INTERPOLATION_PERIOD = 0x60C2  # RECORD: 1 = value (UNSIGNED8), 2 = index (INTEGER8, 10^index s)
DIGITAL_INPUTS = 0x60FD  # UNSIGNED32; bits 16-31 manufacturer-specific
SUPPORTED_DRIVE_MODES = 0x6502  # UNSIGNED32, bit 9 = cyclic synchronous torque

#: CiA 402 device profile number in the low word of 0x1000.
DEVICE_PROFILE_402 = 402
#: Modes of operation (0x6060): cyclic synchronous torque mode.
MODE_CST = 10
#: Bit of 0x6502 that says CST is supported.
SUPPORTED_CST_BIT = 1 << 9


class State(enum.Enum):
    """The states of the CiA 402 power state machine (statusword 0x6041 bits 0-3, 5, 6)."""

    NOT_READY_TO_SWITCH_ON = 'not ready to switch on'
    SWITCH_ON_DISABLED = 'switch on disabled'
    READY_TO_SWITCH_ON = 'ready to switch on'
    SWITCHED_ON = 'switched on'
    OPERATION_ENABLED = 'operation enabled'
    QUICK_STOP_ACTIVE = 'quick stop active'
    FAULT_REACTION_ACTIVE = 'fault reaction active'
    FAULT = 'fault'


#: (mask, value) of the statusword for each state, CiA 402 table "state coding".
_STATE_CODING = (
    (0x004F, 0x0000, State.NOT_READY_TO_SWITCH_ON),
    (0x004F, 0x0040, State.SWITCH_ON_DISABLED),
    (0x006F, 0x0021, State.READY_TO_SWITCH_ON),
    (0x006F, 0x0023, State.SWITCHED_ON),
    (0x006F, 0x0027, State.OPERATION_ENABLED),
    (0x006F, 0x0007, State.QUICK_STOP_ACTIVE),
    (0x004F, 0x000F, State.FAULT_REACTION_ACTIVE),
    (0x004F, 0x0008, State.FAULT),
)

# Statusword bits besides the state coding.
SW_FAULT = 1 << 3
SW_VOLTAGE_ENABLED = 1 << 4
SW_WARNING = 1 << 7
SW_REMOTE = 1 << 9
SW_TARGET_REACHED = 1 << 10
SW_FOLLOWS_TARGET = 1 << 12  # cyclic modes: 1 = the drive follows the target, 0 = ignores it


def decode_state(statusword: int) -> State | None:
    """Return the CiA 402 state coded in statusword 0x6041, or None for an undefined pattern."""
    for mask, value, state in _STATE_CODING:
        if statusword & mask == value:
            return state
    return None


def encode_statusword(state: State, remote: bool = True, warning: bool = False) -> int:
    """Return the statusword 0x6041 a drive reports in ``state``.

    Voltage-enabled bit 4 while powered.
    """
    base = {
        State.NOT_READY_TO_SWITCH_ON: 0x0000,
        State.SWITCH_ON_DISABLED: 0x0040,
        State.READY_TO_SWITCH_ON: 0x0021,
        State.SWITCHED_ON: 0x0023,
        State.OPERATION_ENABLED: 0x0027,
        State.QUICK_STOP_ACTIVE: 0x0007,
        State.FAULT_REACTION_ACTIVE: 0x000F,
        State.FAULT: 0x0008,
    }[state]
    if state in (
        State.READY_TO_SWITCH_ON,
        State.SWITCHED_ON,
        State.OPERATION_ENABLED,
        State.QUICK_STOP_ACTIVE,
    ):
        base |= SW_VOLTAGE_ENABLED
    return base | (SW_REMOTE if remote else 0) | (SW_WARNING if warning else 0)


class Command(enum.Enum):
    """Device control commands of the controlword 0x6040 (CiA 402 table "command coding")."""

    SHUTDOWN = 0x0006
    SWITCH_ON = 0x0007  # also "disable operation" from operation enabled
    ENABLE_OPERATION = 0x000F
    DISABLE_VOLTAGE = 0x0000
    QUICK_STOP = 0x0002
    FAULT_RESET = 0x0080  # acts on the rising edge of bit 7


CW_FAULT_RESET = 1 << 7
CW_HALT = 1 << 8


def decode_command(controlword: int) -> Command:
    """Return the device control command in controlword 0x6040 (bits 0-3; bit 7 = fault reset)."""
    if controlword & CW_FAULT_RESET:
        return Command.FAULT_RESET
    if not controlword & 0x2:
        return Command.DISABLE_VOLTAGE
    if not controlword & 0x4:
        return Command.QUICK_STOP
    if not controlword & 0x1:
        return Command.SHUTDOWN
    if not controlword & 0x8:
        return Command.SWITCH_ON
    return Command.ENABLE_OPERATION


#: State machine transitions on a command: (state, command) -> next state (CiA 402 transitions
#: 2-12 and 15). A command not listed leaves the state unchanged.
TRANSITIONS = {
    (State.SWITCH_ON_DISABLED, Command.SHUTDOWN): State.READY_TO_SWITCH_ON,  # 2
    (State.READY_TO_SWITCH_ON, Command.SWITCH_ON): State.SWITCHED_ON,  # 3
    (State.SWITCHED_ON, Command.ENABLE_OPERATION): State.OPERATION_ENABLED,  # 4
    (State.OPERATION_ENABLED, Command.SWITCH_ON): State.SWITCHED_ON,  # 5
    (State.SWITCHED_ON, Command.SHUTDOWN): State.READY_TO_SWITCH_ON,  # 6
    (State.READY_TO_SWITCH_ON, Command.DISABLE_VOLTAGE): State.SWITCH_ON_DISABLED,  # 7
    (State.READY_TO_SWITCH_ON, Command.QUICK_STOP): State.SWITCH_ON_DISABLED,  # 7
    (State.OPERATION_ENABLED, Command.SHUTDOWN): State.READY_TO_SWITCH_ON,  # 8
    (State.OPERATION_ENABLED, Command.DISABLE_VOLTAGE): State.SWITCH_ON_DISABLED,  # 9
    (State.SWITCHED_ON, Command.DISABLE_VOLTAGE): State.SWITCH_ON_DISABLED,  # 10
    (State.SWITCHED_ON, Command.QUICK_STOP): State.SWITCH_ON_DISABLED,  # 10
    (State.OPERATION_ENABLED, Command.QUICK_STOP): State.QUICK_STOP_ACTIVE,  # 11
    (State.QUICK_STOP_ACTIVE, Command.DISABLE_VOLTAGE): State.SWITCH_ON_DISABLED,  # 12
    (State.FAULT, Command.FAULT_RESET): State.SWITCH_ON_DISABLED,  # 15
}


def next_state(state: State, command: Command) -> State:
    """Return the state after ``command`` in ``state``.

    CiA 402 transitions; unknown pairs keep the state.
    """
    return TRANSITIONS.get((state, command), state)


#: Controlword sequences that bring a drive from a state to operation enabled.
ENABLE_SEQUENCE = (Command.SHUTDOWN, Command.SWITCH_ON, Command.ENABLE_OPERATION)

#: Texts of the error codes (0x603F, EMCY) this project's drive uses, CiA 402 annex / CiA 301.
ERROR_TEXTS = {
    0x0000: 'no error',
    0x2310: 'continuous over-current',
    0x2320: 'short circuit / earth leakage',
    0x3210: 'DC link over-voltage',
    0x4210: 'excess temperature device',
    0x5000: 'device hardware',
    0x8110: 'CAN overrun (objects lost)',
    0x8130: 'life guard or heartbeat error',
    0x8611: 'following error',
    0xFF00: 'device specific',
}


def error_text(code: int) -> str:
    """Text of a CiA 402 / CiA 301 error code (0x603F or EMCY), by exact code then by its class."""
    if code in ERROR_TEXTS:
        return ERROR_TEXTS[code]
    classes = {
        0x1: 'generic error',
        0x2: 'current',
        0x3: 'voltage',
        0x4: 'temperature',
        0x5: 'device hardware',
        0x6: 'device software',
        0x7: 'additional modules',
        0x8: 'monitoring',
        0x9: 'external error',
        0xF: 'additional functions',
    }
    return classes.get(code >> 12, 'unknown error') + f' (code 0x{code:04X})'
