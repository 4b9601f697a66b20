# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The simulated drive's settings as specs (parameters 'sim.*' of a runner's joint).

Each is a command-line option of ``cia402_sim_drive`` (``arguments``); the faults and quirks
they stand for are in sim_faults.py. ROS-free.
"""

from __future__ import annotations

from dataclasses import dataclass

from actuator_cia402.sim_faults import FAULT_CODES, Quirks, mapping_entry
from actuator_core import limits
from actuator_core.params import spec, validate

CONDITIONS = ('deep_sea', 'lab')


@dataclass(frozen=True)
class SimDriveSettings:
    """The simulated drive (parameters 'sim.*'; used only with simulated_drive true)."""

    working_condition: str = spec(
        'deep_sea', 'joint model condition: deep_sea (10 MPa, 2 degC) or lab (0 MPa, 25 degC)'
    )
    torque_time_constant_s: float = spec(
        2.0e-4, 'time constant of the drive torque loop (first order)', 's', 0.0, 0.01
    )
    initial_position_rad: float = spec(0.0, 'joint angle at start', 'rad', -100.0, 100.0)
    load: bool = spec(
        True,
        "the joint carries the paper's external torque (eq. (40), 10-30 N m); false: a free "
        'joint, as on a first power-on',
    )
    fault_kind: str = spec(
        'none', 'fault to inject: none, over_current (0x2310) or following_error (0x8611)'
    )
    fault_at_s: float = spec(
        -1.0, 'time of the injected fault after the first SYNC (negative: never)', 's', -1.0, 1.0e6
    )
    emcy_code: int = spec(
        0xFF00, 'code of an extra EMCY frame (error register 0: a warning)', '', 1, 0xFFFF
    )
    emcy_at_s: float = spec(
        -1.0,
        'time of the extra EMCY frame after the first SYNC (negative: never)',
        's',
        -1.0,
        1.0e6,
    )
    over_current_a: float = spec(
        1.25 * limits.CURRENT_LIMIT_A,
        'the drive faults (0x2310) beyond this motor current',
        'A',
        0.0,
        1.0e3,
        low_open=True,
    )
    drop_tpdo_fraction: float = spec(
        0.0, 'share of SYNCs the drive answers without TPDOs', '', 0.0, 1.0
    )
    late_tpdo_fraction: float = spec(
        0.0,
        "share of SYNCs the drive answers only just before the next SYNC's TPDOs",
        '',
        0.0,
        1.0,
    )
    silent_at_s: float = spec(
        -1.0,
        'time after the first SYNC from which the drive is silent (negative: never)',
        's',
        -1.0,
        1.0e6,
    )
    seed: int = spec(1, 'seed of the dropped- and late-TPDO draws', '', 0, 2**31 - 1)
    emcy_register: int = spec(
        0,
        'error register of the extra EMCY frame (nonzero: a fault the drive reports while it '
        'stays enabled)',
        '',
        0,
        0xFF,
    )
    transition_16: bool = spec(
        False,
        'quick stop active returns to operation enabled on an enable-operation command under '
        'quick stop option codes 5-8 (CiA 402 transition 16)',
    )
    halted_bit: bool = spec(
        True, 'statusword bit 10 is set in quick stop active once the drive has halted'
    )
    velocity_quick_stop: bool = spec(
        False,
        'quick stop decelerates the motor at 0x6085 (rpm/s) instead of ramping the torque at '
        '0x6087',
    )
    produces_sync: bool = spec(
        False, 'the drive produces SYNC itself at power-on (0x1005 bit 30 saved in the drive)'
    )
    fixed_mapping_entry: str = spec(
        '',
        'a PDO mapping entry INDEX:SUB (hex, e.g. 1A01:3) the drive keeps at its EDS default: '
        'written without an error, never taken',
    )
    encoder_sign: int = spec(
        1,
        'direction of the encoder against the motor torque: -1 counts against a positive '
        'torque (a wiring error)',
        '',
        -1,
        1,
    )

    def __post_init__(self) -> None:
        """Refuse an unknown condition, fault kind, mapping entry or encoder sign."""
        validate(self)
        try:
            self.quirks
        except ValueError as exc:
            raise ValueError(f'sim.{exc}') from None
        if self.working_condition not in CONDITIONS:
            raise ValueError(
                f'sim.working_condition = {self.working_condition!r} refused: one of '
                f'{", ".join(CONDITIONS)}'
            )
        if self.fault_kind not in ('none', *FAULT_CODES):
            raise ValueError(
                f'sim.fault_kind = {self.fault_kind!r} refused: one of none, '
                f'{", ".join(FAULT_CODES)}'
            )

    def arguments(self) -> list[str]:
        """Return the command line of cia402_sim_drive for these settings."""
        return [
            '--working-condition',
            self.working_condition,
            '--torque-time-constant',
            repr(self.torque_time_constant_s),
            '--initial-position',
            repr(self.initial_position_rad),
            '--fault-kind',
            self.fault_kind,
            '--fault-at',
            repr(self.fault_at_s),
            '--emcy-code',
            str(self.emcy_code),
            '--emcy-at',
            repr(self.emcy_at_s),
            '--over-current',
            repr(self.over_current_a),
            '--drop-tpdo',
            repr(self.drop_tpdo_fraction),
            '--late-tpdo',
            repr(self.late_tpdo_fraction),
            '--silent-at',
            repr(self.silent_at_s),
            '--seed',
            str(self.seed),
            '--emcy-register',
            str(self.emcy_register),
            '--encoder-sign',
            str(self.encoder_sign),
        ] + self._quirk_flags()

    def _quirk_flags(self) -> list[str]:
        """Return the command-line flags of the quirks that depart from the kind drive."""
        flags = [
            flag
            for flag, on in (
                ('--no-load', not self.load),
                ('--transition-16', self.transition_16),
                ('--no-halted-bit', not self.halted_bit),
                ('--velocity-quick-stop', self.velocity_quick_stop),
                ('--produces-sync', self.produces_sync),
            )
            if on
        ]
        if self.fixed_mapping_entry:
            flags += ['--fixed-mapping-entry', self.fixed_mapping_entry]
        return flags

    @property
    def quirks(self) -> Quirks:
        """The simulated drive's departures from a kind drive (ValueError when malformed)."""
        return Quirks(
            transition_16=self.transition_16,
            halted_bit=self.halted_bit,
            velocity_quick_stop=self.velocity_quick_stop,
            sync_producer=self.produces_sync,
            fixed_mapping_entry=mapping_entry(self.fixed_mapping_entry),
            encoder_sign=self.encoder_sign,
        )
