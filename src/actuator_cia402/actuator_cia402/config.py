# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The driver's parameters as specs (unit, valid range, description).

One declaration for ROS and docs. ROS-free: the driver node declares them with
actuator_ros.parameters.declare_spec_parameters, launch_spec builds them for a closed-loop run, and
docs/reference/parameters.md lists them (generated).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Optional

from actuator_cia402.busload import DEFAULT_LIMIT, MAX_JOINTS_ON_BUS, check_bus_load
from actuator_cia402.scaling import Scaling
from actuator_cia402.supervision import HEARTBEAT_PERIODS_MISSED
from actuator_core import limits
from actuator_core.params import spec, validate

INTERFACES = ('hub', 'socketcan')
#: Rated current of the joint motor [A] and its rated torque k_tn * I_rated [N m]
#: (EDS 0x6075, 0x6076).
RATED_CURRENT_A = 10.0
RATED_TORQUE_NM = RATED_CURRENT_A * limits.NOMINAL_TORQUE_CONSTANT_NM_A
#: The simulated drive's brake status: 0x60FD bit 16 (manufacturer-specific), brake closed.
SIM_BRAKE_STATUS = (0x60FD, 1 << 16)
#: Quick stop deceleration written to the simulated drive when none is set [rad/s^2 at the
#: joint]: 2 rad/s to rest in 20 ms. A real drive has no default (``check_real_drive``).
SIM_QUICK_STOP_DECELERATION_RAD_S2 = 100.0


def default_eds() -> str:
    """Return the simulated drive's EDS: installed share, else the source tree's."""
    try:
        from ament_index_python.packages import get_package_share_directory

        return os.path.join(
            get_package_share_directory('actuator_cia402'), 'eds', 'sim_joint_drive.eds'
        )
    except (ImportError, LookupError):
        here = os.path.dirname(os.path.abspath(__file__))
        return os.path.join(here, '..', 'eds', 'sim_joint_drive.eds')


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
        -1,
        'object whose bit (brake_status_mask) reads 1 while the brake is closed; 0: the '
        'drive cannot tell (deactivate then waits brake_closing_s); -1: not set (required on '
        "a real drive; the simulated drive's 0x60FD)",
        '',
        -1,
        0xFFFF,
    )
    brake_status_mask: int = spec(
        0,
        "bit mask of brake closed in that object; 0: not set (the simulated drive's bit 16; "
        'required with a brake_status_index on a real drive)',
        '',
        0,
        2**32 - 1,
    )
    quick_stop_deceleration_rad_s2: float = spec(
        0.0,
        'quick stop deceleration of a velocity-based quick stop at the joint, written as 0x6085 '
        'in motor rpm/s; 0: not set (required on a real drive)',
        'rad/s^2',
        0.0,
        1.0e5,
    )
    drive_heartbeat_period_s: float = spec(
        0.1,
        "the drive's heartbeat 0x1017, consumed here: a boot-up after configure (a reboot) "
        f'refuses activation and ends control; {HEARTBEAT_PERIODS_MISSED} periods of silence '
        'refuse activation',
        's',
        0.001,
        10.0,
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
    def brake_status(self) -> tuple[int, int]:
        """(object, mask) of the brake's 'closed' bit: the simulated drive's where not set."""
        if self.brake_status_index < 0:
            return SIM_BRAKE_STATUS
        return self.brake_status_index, self.brake_status_mask or SIM_BRAKE_STATUS[1]

    @property
    def quick_stop_deceleration_rpm_s(self) -> int:
        """0x6085 in motor rpm/s: the joint's deceleration x N (the simulated one if not set)."""
        joint = self.quick_stop_deceleration_rad_s2 or SIM_QUICK_STOP_DECELERATION_RAD_S2
        return math.ceil(joint * self.gear_ratio * 60.0 / (2.0 * math.pi))

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
        return default_eds()


def check_real_drive(
    drive: DriverParameters, position_limits_rad: Optional[tuple[float, float]] = None
) -> None:
    """Refuse a real drive (not simulated_drive) whose drive-specific settings are not set.

    The brake status object, the quick stop deceleration and (given) the soft position limits
    have defaults only for the simulated drive and plant; ValueError names every one missing.
    """
    if drive.simulated_drive:
        return
    missing = []
    if drive.brake_status_index < 0:
        missing.append('brake_status_index (0: the drive cannot tell)')
    elif drive.brake_status_index and not drive.brake_status_mask:
        missing.append('brake_status_mask')
    if not drive.quick_stop_deceleration_rad_s2:
        missing.append('quick_stop_deceleration_rad_s2 (0x6085)')
    if position_limits_rad is not None:
        low, high = position_limits_rad
        if low <= -limits.POSITION_LIMIT_RAD or high >= limits.POSITION_LIMIT_RAD:
            missing.append("position_min_rad and position_max_rad (the joint's travel)")
    if missing:
        raise ValueError(
            f'a real drive needs {", ".join(missing)} set: the defaults are the simulated '
            "drive's and plant's"
        )
