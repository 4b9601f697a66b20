# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The driver's parameters as specs (unit, valid range, description).

One declaration for ROS and docs. ROS-free: the driver node declares them with
actuator_ros.parameters.declare_spec_parameters, launch_spec builds them for a closed-loop run, the
README lists them.
"""

from __future__ import annotations

from dataclasses import dataclass

from actuator_core import limits
from actuator_core.params import spec, validate
from actuator_cia402.busload import DEFAULT_LIMIT, MAX_JOINTS_ON_BUS, check_bus_load
from actuator_cia402.scaling import Scaling
from actuator_cia402.sim_faults import FAULT_CODES, Quirks, mapping_entry

INTERFACES = ('hub', 'socketcan')
CONDITIONS = ('deep_sea', 'lab')
#: Rated current of the joint motor [A] and its rated torque k_tn * I_rated [N m]
#: (EDS 0x6075, 0x6076).
RATED_CURRENT_A = 10.0
RATED_TORQUE_NM = RATED_CURRENT_A * limits.NOMINAL_TORQUE_CONSTANT_NM_A


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


@dataclass(frozen=True)
class DriverParameters:
    """Every constant of the CiA 402 drive and its bus (the joint node's common ones apart).

    ``sync_period_s`` and ``current_limit_a`` are the joint node's ``sample_time_s`` and
    ``current_limit_a`` (JointSettings): the driver node fills them in, it does not declare them.
    """

    node_id: int = spec(1, 'CANopen node id of the drive', '', 1, 127)
    interface: str = spec(
        'socketcan', 'CAN interface: socketcan, or hub (the simulated bus over loopback TCP)'
    )
    channel: str = spec('can0', 'CAN channel: can0 (socketcan) or 127.0.0.1:PORT (hub)')
    master_node_id: int = spec(
        127, 'node id of this master: its heartbeat goes out on 0x700 + this id', '', 1, 127
    )
    sync_producer: bool = spec(
        True, 'this joint sends the SYNC (one producer per bus; the others wait for it)'
    )
    heartbeat_period_s: float = spec(
        0.01, 'period of the master heartbeat (0x700 + master_node_id)', 's', 0.001, 1.0
    )
    heartbeat_timeout_s: float = spec(
        0.3,
        "drive's heartbeat consumer time 0x1016: the drive quick-stops (0x6007 = 3) when "
        'the master heartbeat is silent this long',
        's',
        0.002,
        10.0,
    )
    sync_window_fraction: float = spec(
        2.0,
        'SYNC window 0x1007 in SYNC periods: the RPDO goes out just before the SYNC it is '
        'for, so the window must exceed one period; later RPDOs are discarded',
        '',
        1.05,
        10.0,
    )
    zero_offset_rad: float = spec(
        0.0, 'joint angle = unwrapped position actual - this offset', 'rad', -1.0e6, 1.0e6
    )
    polarity: int = spec(
        0, 'expected polarity 0x607E (set in the drive tool); checked', '', 0, 255
    )
    velocity_limit_rad_s: float = spec(
        limits.VELOCITY_LIMIT_RAD_S,
        'joint speed limit, written as max motor speed 0x6080 [rpm]',
        'rad/s',
        0.0,
        1.0e4,
        low_open=True,
    )
    torque_slope_permille_s: int = spec(
        10000, 'torque slope 0x6087 of the quick-stop and disable ramps', 'per mille/s', 1, 10**7
    )
    brake_status_index: int = spec(
        0x60FD,
        'object whose bit (brake_status_mask) reads 1 while the brake is closed; 0: the '
        'drive cannot tell (deactivate then waits brake_closing_s)',
        '',
        0,
        0xFFFF,
    )
    brake_status_mask: int = spec(
        1 << 16, 'bit mask of brake closed in that object', '', 1, 2**32 - 1
    )
    brake_closing_s: float = spec(
        0.1, 'longest wait for the brake to report closed after the ramp', 's', 0.0, 10.0
    )
    bitrate: int = spec(
        1_000_000,
        'CAN bitrate (socketcan: set with ip link, checked here for the bus load)',
        'bit/s',
        10_000,
        1_000_000,
    )
    sync_period_s: float = spec(
        limits.SAMPLE_TIME_S,
        'SYNC period = sample time (1 kHz; 500 Hz = 0.002)',
        's',
        2.5e-4,
        0.01,
    )
    rpdo_cob_id: int = spec(
        0, 'COB-ID of RPDO1 (controlword, target torque); 0 = 0x200 + node_id', '', 0, 0x7FF
    )
    tpdo1_cob_id: int = spec(
        0, 'COB-ID of TPDO1 (statusword, position, torque); 0 = 0x180 + node_id', '', 0, 0x7FF
    )
    tpdo2_cob_id: int = spec(
        0, 'COB-ID of TPDO2 (current, error code, mode display); 0 = 0x280 + node_id', '', 0, 0x7FF
    )
    encoder_counts_per_rev: int = spec(
        4096, 'motor encoder counts per motor revolution (0x608F)', 'counts/rev', 1, 2**24
    )
    gear_ratio: float = spec(
        limits.NOMINAL_GEAR_RATIO,
        'N: motor revolutions per joint revolution',
        '',
        0.0,
        1.0e4,
        low_open=True,
    )
    rated_torque_nm: float = spec(
        RATED_TORQUE_NM,
        'motor rated torque (0x6076): 1000 per mille',
        'N m',
        0.0,
        1.0e3,
        low_open=True,
    )
    rated_current_a: float = spec(
        RATED_CURRENT_A,
        'motor rated current (0x6075): 1000 per mille',
        'A',
        0.0,
        1.0e3,
        low_open=True,
    )
    torque_constant_nm_a: float = spec(
        limits.NOMINAL_TORQUE_CONSTANT_NM_A,
        'k_t: motor torque per current',
        'N m/A',
        0.0,
        100.0,
        low_open=True,
    )
    current_limit_a: float = spec(
        limits.CURRENT_LIMIT_A,
        'commands beyond +-this are refused (0 A applied)',
        'A',
        *limits.CURRENT_LIMIT_RANGE_A,
        low_open=True,
    )
    state_timeout_s: float = spec(
        1.0, 'longest wait for the drive to reach a CiA 402 state in a transition', 's', 0.01, 60.0
    )
    sdo_timeout_s: float = spec(
        0.3, 'SDO response timeout (configure, activate, deactivate only)', 's', 0.001, 10.0
    )
    first_sync_timeout_s: float = spec(
        5.0,
        "a SYNC consumer (sync_producer false) ends control when the bus's producer has sent "
        'no SYNC this long after activation (another joint may start later)',
        's',
        *limits.TIMEOUT_RANGE_S,
    )
    feedback_timeout_s: float = spec(
        0.05,
        'control ends after this much time in cycles without a TPDO (the cycles the master '
        'ran, in a row)',
        's',
        *limits.TIMEOUT_RANGE_S,
    )
    tpdo_wait_fraction: float = spec(
        0.5, 'how long a cycle waits for TPDO1 after SYNC, in sync periods', '', 0.05, 0.9
    )
    joints_on_bus: int = spec(
        1,
        'drives whose cycles share this bus and its one SYNC: the bus load is checked for all',
        '',
        1,
        MAX_JOINTS_ON_BUS,
    )
    bus_load_limit: float = spec(
        DEFAULT_LIMIT,
        'refuse a worst-case bus load above this share of the bitrate',
        '',
        0.0,
        1.0,
        low_open=True,
    )
    eds_file: str = spec(
        '',
        "the drive's EDS (required on a real bus); empty with simulated_drive = the "
        "simulated drive's share/actuator_cia402/eds/sim_joint_drive.eds",
    )
    simulated_drive: bool = spec(
        False, "the drive is this project's simulated drive (process cia402_sim_drive on a hub)"
    )

    def __post_init__(self) -> None:
        """Range checks, then the combinations.

        interface, simulated drive on socketcan, bus load.
        """
        validate(self)
        if self.interface not in INTERFACES:
            raise ValueError(
                f'interface = {self.interface!r} refused: one of {", ".join(INTERFACES)}'
            )
        if self.simulated_drive and self.interface != 'hub':
            raise ValueError(
                'simulated_drive = true needs interface = hub (the simulated drive process '
                'cia402_sim_drive serves its bus on 127.0.0.1)'
            )
        if self.master_node_id == self.node_id:
            raise ValueError(f'master_node_id = {self.master_node_id} is the drive node_id')
        if self.heartbeat_timeout_s < 2 * self.heartbeat_period_s:
            raise ValueError(
                f'heartbeat_timeout_s = {self.heartbeat_timeout_s} must be at least twice '
                f'heartbeat_period_s = {self.heartbeat_period_s}'
            )
        check_bus_load(
            self.bitrate, self.sync_period_s, limit=self.bus_load_limit, joints=self.joints_on_bus
        )

    @property
    def scaling(self) -> Scaling:
        """The unit conversions of this drive."""
        return Scaling(
            self.encoder_counts_per_rev,
            self.gear_ratio,
            self.rated_torque_nm,
            self.rated_current_a,
            self.torque_constant_nm_a,
        )

    @property
    def cob_ids(self) -> tuple[int, int, int]:
        """COB-IDs of RPDO1, TPDO1, TPDO2 (CiA 301 pre-defined connection set where 0)."""
        return (
            self.rpdo_cob_id or 0x200 + self.node_id,
            self.tpdo1_cob_id or 0x180 + self.node_id,
            self.tpdo2_cob_id or 0x280 + self.node_id,
        )

    def eds_path(self) -> str:
        """Return the EDS file to read.

        The installed one of the simulated drive unless eds_file is set.
        """
        if self.eds_file:
            return self.eds_file
        if not self.simulated_drive:
            raise ValueError(
                "eds_file must name the drive's EDS on a real bus (the simulated drive's EDS is "
                'used only with simulated_drive = true)'
            )
        from actuator_cia402.sim_drive_main import default_eds

        return default_eds()
