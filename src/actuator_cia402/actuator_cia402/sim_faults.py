# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What the simulated drive (sim_drive.py) can be made to do wrong: the fault plan and its events.

Drive faults (fault reaction, 0x603F, EMCY), an extra EMCY (error register 0: a warning; else
a fault the drive reports while it stays enabled), dropped TPDOs, a silent drive (a cut cable),
and events: STO (operation left without a fault, voltage off), a quick-stop input, remote off
(local control), 'target ignored' (statusword bit 12 low), bus-off and error-passive (error
frames the hub sends; the process main does that), a reboot that loses the configuration.

``Quirks``: where the drive departs from a kind one, as real drives do (all off by default):
transition 16 under quick stop option codes 5-8, no statusword bit 10 in quick stop active, a
quick stop that decelerates the motor at 0x6085 instead of ramping the torque, a drive that
produces SYNC itself (0x1005 bit 30), a PDO mapping entry it keeps whatever is written, and an
encoder that counts against the motor's positive torque (a wiring error).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from actuator_cia402 import profile as p
from actuator_plant.model import PlantParameters, WorkingCondition

FAULT_CODES = {'over_current': 0x2310, 'following_error': 0x8611}
#: Injectable events besides the faults (FaultPlan.inject).
INJECTIONS = (
    'sto',
    'quick_stop_input',
    'remote_off',
    'target_ignored',
    'bus_off',
    'error_passive',
    'reboot',
)


@dataclass(frozen=True)
class FaultPlan:
    """Faults and events to inject, t [s] after the first SYNC the drive saw (negative: never)."""

    fault_kind: str = 'none'  # 'none', 'over_current' or 'following_error'
    fault_at_s: float = -1.0
    emcy_code: int = 0xFF00  # extra EMCY frame (error register 0: a warning, no fault)
    emcy_at_s: float = -1.0
    drop_tpdo_fraction: float = 0.0  # share of SYNCs answered without TPDOs
    silent_at_s: float = -1.0  # from then on the drive is silent (no TPDO, SDO, heartbeat)
    seed: int = 1
    inject: tuple = ()  # ((kind, t_s), ...) with kind in INJECTIONS
    late_tpdo_fraction: float = 0.0  # share of SYNCs answered only after the next SYNC
    emcy_register: int = 0  # error register of the extra EMCY (nonzero: a fault, drive enabled)

    def __post_init__(self) -> None:
        """Refuse an unknown kind or a fraction outside [0, 1]."""
        if self.fault_kind not in ('none', *FAULT_CODES):
            raise ValueError(
                f'fault_kind must be none, {", ".join(FAULT_CODES)}; got {self.fault_kind!r}'
            )
        for name in ('drop_tpdo_fraction', 'late_tpdo_fraction'):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f'{name} must be in [0, 1], got {getattr(self, name)}')
        for kind, _ in self.inject:
            if kind not in INJECTIONS:
                raise ValueError(
                    f'inject kind must be one of {", ".join(INJECTIONS)}, got {kind!r}'
                )


@dataclass(frozen=True)
class Quirks:
    """How the simulated drive departs from a kind drive, each as real drives may."""

    transition_16: bool = False  # quick stop active -> operation enabled on enable (0x605A 5-8)
    halted_bit: bool = True  # statusword bit 10 set in quick stop active once halted
    velocity_quick_stop: bool = False  # quick stop decelerates the motor at 0x6085
    sync_producer: bool = False  # 0x1005 bit 30 set at power-on: the drive sends SYNC
    fixed_mapping_entry: Optional[tuple[int, int]] = None  # (index, sub) kept at its default
    encoder_sign: int = 1  # -1: the encoder counts against the motor's positive torque

    def __post_init__(self) -> None:
        """Refuse an encoder sign other than +-1."""
        if self.encoder_sign not in (1, -1):
            raise ValueError(f'encoder_sign must be 1 or -1, got {self.encoder_sign}')


def mapping_entry(text: str) -> Optional[tuple[int, int]]:
    """'1A01:3' -> (0x1A01, 3), a PDO mapping entry (hex index, subindex); '' -> None."""
    if not text:
        return None
    index, _, sub = text.partition(':')
    try:
        entry = int(index, 16), int(sub, 0)
    except ValueError:
        entry = (0, 0)
    if not (0x1600 <= entry[0] <= 0x17FF or 0x1A00 <= entry[0] <= 0x1BFF) or not entry[1] > 0:
        raise ValueError(
            f'a PDO mapping entry is INDEX:SUB with INDEX 1600-17FF or 1A00-1BFF (hex) and SUB '
            f'>= 1, e.g. 1A01:3; got {text!r}'
        )
    return entry


def plant_parameters(working_condition: str, load: bool = True) -> PlantParameters:
    """Return the joint model of the paper in 'deep_sea' (10 MPa, 2 degC) or 'lab'.

    ``load``: with the external torque of eq. (40); without it the joint is free.
    """
    conditions = {'deep_sea': WorkingCondition.deep_sea, 'lab': WorkingCondition.lab}
    if working_condition not in conditions:
        raise ValueError(f'working_condition must be deep_sea or lab, got {working_condition!r}')
    return PlantParameters(condition=conditions[working_condition](), with_external_torque=load)


def inject_due(drive, t_s: float) -> None:
    """Apply the faults and events of ``drive.faults`` that are due at drive time ``t_s``."""
    f = drive.faults
    if 0.0 <= f.silent_at_s <= t_s and not drive.silent:
        drive.silent = True
        drive._event('silent')
    if f.fault_kind != 'none' and 0.0 <= f.fault_at_s <= t_s and 'fault' not in drive._injected:
        drive._injected.add('fault')
        drive._raise_fault(FAULT_CODES[f.fault_kind])
    if 0.0 <= f.emcy_at_s <= t_s and 'emcy' not in drive._injected:
        drive._injected.add('emcy')
        drive._send_emcy(f.emcy_code, f.emcy_register)
    for kind, at_s in f.inject:
        if 0.0 <= at_s <= t_s and kind not in drive._injected:
            drive._injected.add(kind)
            drive._event(f'injected: {kind}')
            if kind == 'sto':
                drive.sto = True
                if drive.state is not p.State.FAULT:
                    drive._stopping, drive.ramp_permille = None, 0.0
                    drive.state = p.State.SWITCH_ON_DISABLED
                drive._close_brake()
            elif kind == 'quick_stop_input' and drive.state is p.State.OPERATION_ENABLED:
                drive.quick_stop()
            elif kind == 'remote_off':
                drive.remote_off = True
            elif kind == 'target_ignored':
                drive.target_ignored = True
            elif kind == 'reboot':
                drive.reboot()
            # bus_off / error_passive: the hub sends the error frame (on_event)
