# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The driver's parameters as specs (unit, valid range, description).

One declaration for ROS and docs. ROS-free: the driver node declares them with
actuator_ros.parameters.declare_spec_parameters, launch_spec builds them for a closed-loop run, the
README lists them.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from actuator_core import limits
from actuator_core.params import spec, validate
from actuator_cia402.busload import DEFAULT_LIMIT, check_bus_load
from actuator_cia402.scaling import Scaling
from actuator_cia402.sim_drive import FAULT_CODES, FaultPlan

INTERFACES = ('virtual', 'socketcan')
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
        -1.0, 'drive time of the injected fault (negative: never)', 's', -1.0, 1.0e6
    )
    emcy_code: int = spec(
        0xFF00, 'code of an extra EMCY frame (error register 0: a warning)', '', 1, 0xFFFF
    )
    emcy_at_s: float = spec(
        -1.0, 'drive time of the extra EMCY frame (negative: never)', 's', -1.0, 1.0e6
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
    silent_at_s: float = spec(
        -1.0, 'drive time from which the drive is silent (negative: never)', 's', -1.0, 1.0e6
    )
    seed: int = spec(1, 'seed of the dropped-TPDO draw', '', 0, 2**31 - 1)

    def __post_init__(self) -> None:
        """Refuse an unknown condition or fault kind."""
        validate(self)
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

    def fault_plan(self) -> FaultPlan:
        """Return the faults to inject, as the simulated drive takes them."""
        return FaultPlan(
            self.fault_kind,
            self.fault_at_s,
            self.emcy_code,
            self.emcy_at_s,
            self.drop_tpdo_fraction,
            self.silent_at_s,
            self.seed,
        )


@dataclass(frozen=True)
class DriverParameters:
    """Every constant of the CiA 402 driver node."""

    node_id: int = spec(1, 'CANopen node id of the drive', '', 1, 127)
    interface: str = spec('virtual', 'python-can interface: virtual (in-process bus) or socketcan')
    channel: str = spec('can0', 'CAN channel, e.g. can0 (socketcan) or any bus name (virtual)')
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
        0, 'COB-ID of TPDO2 (current, error code); 0 = 0x280 + node_id', '', 0, 0x7FF
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
    command_timeout_s: float = spec(
        limits.COMMAND_TIMEOUT_S,
        '0 A and brake once the newest command is older',
        's',
        *limits.TIMEOUT_RANGE_S,
    )
    brake_delay_s: float = spec(
        0.1,
        'a safe stop or command timeout lasting this long disables operation '
        '(holding brake); shorter ones apply 0 A in operation',
        's',
        0.0,
        10.0,
    )
    state_timeout_s: float = spec(
        1.0, 'longest wait for the drive to reach a CiA 402 state in a transition', 's', 0.01, 60.0
    )
    sdo_timeout_s: float = spec(
        0.3, 'SDO response timeout (configure, activate, deactivate only)', 's', 0.001, 10.0
    )
    feedback_timeout_s: float = spec(
        0.05, 'error when no TPDO arrived for this long', 's', *limits.TIMEOUT_RANGE_S
    )
    tpdo_wait_fraction: float = spec(
        0.5, 'how long a cycle waits for TPDO1 after SYNC, in sync periods', '', 0.05, 0.9
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
        '', "the drive's EDS; empty = share/actuator_cia402/eds/sim_joint_drive.eds"
    )
    joint_name: str = spec('joint', 'name in joint_states')
    autostart: bool = spec(
        False, 'configure and activate at start (otherwise: ros2 lifecycle set)'
    )
    simulated_drive: bool = spec(
        False, 'run the simulated drive in this process on the virtual bus'
    )
    wait_for_subscribers: int = spec(
        0, 'autostart: activate once joint_states has this many subscribers', '', 0, 100
    )
    stop_after_s: float = spec(
        0.0, 'deactivate and exit 0 after this long active; 0 = run until stopped', 's', 0.0, 1.0e6
    )
    timing_log: str = spec(
        '',
        'at exit write per-sample stamps (.npz: stamp_ns, published_wall_ns, '
        'held_command_stamp_ns), as the plant node does',
    )
    mode: str = spec(
        'realtime',
        "run mode of the suite; 'sim' (lockstep /clock) is refused: a drive runs in real time",
    )
    sample_time_s: float = spec(
        0.0,
        "the scenario's sample time (its '/**' block); when set it must equal "
        'sync_period_s (0: not set)',
        's',
        0.0,
        0.1,
    )
    diagnostics_period_s: float = spec(0.5, 'period of the diagnostics message', 's', 0.05, 60.0)
    sim: SimDriveSettings = field(default_factory=SimDriveSettings)

    def __post_init__(self) -> None:
        """Range checks, then the combinations.

        interface, simulated drive on socketcan, bus load.
        """
        validate(self)
        if self.interface not in INTERFACES:
            raise ValueError(
                f'interface = {self.interface!r} refused: one of {", ".join(INTERFACES)}'
            )
        if self.simulated_drive and self.interface != 'virtual':
            raise ValueError(
                'simulated_drive = true needs interface = virtual '
                '(the simulated drive shares this process; this kernel has no vcan)'
            )
        if self.mode != 'realtime':
            raise ValueError(
                f'mode = {self.mode!r} refused: the CiA 402 driver runs in real time only '
                '(SYNC on the system clock); use the simulated plant for sim mode'
            )
        if self.sample_time_s and abs(self.sample_time_s - self.sync_period_s) > 1e-12:
            raise ValueError(
                f'sample_time_s = {self.sample_time_s} differs from sync_period_s = '
                f'{self.sync_period_s}: '
                'the drive samples once per SYNC'
            )
        check_bus_load(self.bitrate, self.sync_period_s, limit=self.bus_load_limit)

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
        from ament_index_python.packages import get_package_share_directory

        return os.path.join(
            get_package_share_directory('actuator_cia402'), 'eds', 'sim_joint_drive.eds'
        )
