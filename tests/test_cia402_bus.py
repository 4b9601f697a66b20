# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The simulated drive and the CAN hub in this process: what a real drive does on the bus.

A ``Hub`` on 127.0.0.1, a ``SimulatedDrive`` on one ``HubBus`` and a tool (canopen
RemoteNode, SDO and raw frames) on another; the drive's behaviour objects one by one. The
hazards against the joint, with the drive in its own process, are tests/test_cia402_hazards.py.
"""

from __future__ import annotations

import struct
import time

import canopen
import pytest

from actuator_cia402 import profile as p
from actuator_cia402.hub import Hub, HubBus, bus_error, error_frame
from actuator_cia402.scaling import Scaling
from actuator_cia402.sim_drive import SimulatedDrive, plant_parameters
from actuator_cia402.sim_drive_main import default_eds
from actuator_cia402.sim_faults import FaultPlan

pytestmark = pytest.mark.ros  # bus threads in real time over loopback TCP
SCALING = Scaling(4096, 100.0, 1.05, 10.0, 0.105)
DT = 2e-3
NODE = 3


@pytest.fixture
def bus():
    """Make (tool node, drive) on a fresh hub; everything leaves at the end."""
    made = []

    def make(faults=FaultPlan(), **drive_kwargs):
        hub = Hub().start()
        networks = []
        for _ in range(2):
            network = canopen.Network(HubBus(hub.address))
            network.NOTIFIER_CYCLE = 0.05
            network.connect()
            networks.append(network)
        drive = SimulatedDrive(default_eds(), NODE, SCALING, DT, faults=faults, **drive_kwargs)
        drive.attach(networks[0])
        tool = canopen.RemoteNode(NODE, default_eds())
        networks[1].add_node(tool)
        tool.sdo.RESPONSE_TIMEOUT = 1.0
        made.append((hub, networks, drive))
        return tool, drive

    yield make
    for hub, networks, drive in made:
        drive.stop()
        for network in networks:
            network.disconnect()
        hub.stop()


def enable(tool, target_permille: int = 0) -> None:
    """CST, target, enable sequence over SDO (the old driver's way)."""
    tool.sdo[p.MODES_OF_OPERATION].raw = p.MODE_CST
    tool.sdo[p.TARGET_TORQUE].raw = target_permille
    for command in p.ENABLE_SEQUENCE:
        tool.sdo[p.CONTROLWORD].raw = command.value


def rpdo(tool, controlword: int, permille: int) -> None:
    """RPDO1 in the EDS default mapping (controlword, target torque)."""
    tool.network.send_message(0x200 + NODE, struct.pack('<Hh', controlword, permille))


def test_0x6071_is_kept_across_nmt_start_and_enable(bus):
    # The old simulated drive zeroed its RPDO image on NMT start, hiding a stale 0x6071.
    tool, drive = bus()
    tool.sdo[p.TARGET_TORQUE].raw = 400
    tool.nmt.state = 'OPERATIONAL'
    enable(tool, 400)
    time.sleep(0.05)
    assert tool.sdo[p.TARGET_TORQUE].raw == 400
    assert tool.sdo[p.CURRENT_ACTUAL].raw == pytest.approx(400, abs=5)  # 4 A of the 10 A rated
    assert 'operation enabled with 0x6071 = 400 per mille' in drive.events[-2]


def test_an_rpdo_later_than_the_sync_window_is_discarded(bus):
    tool, drive = bus()
    tool.sdo[p.SYNC_WINDOW_US].raw = 1000
    enable(tool)
    tool.nmt.state = 'OPERATIONAL'
    tool.sdo[p.STATUSWORD].raw  # noqa: B018 - NMT taken (in order)
    tool.network.sync.transmit()
    rpdo(tool, p.Command.ENABLE_OPERATION.value, 100)  # in the window
    time.sleep(0.0005)
    tool.network.sync.transmit()
    time.sleep(0.02)
    assert tool.sdo[p.TARGET_TORQUE].raw == 100
    tool.network.sync.transmit()
    time.sleep(0.01)  # 10 ms > the 1 ms window
    rpdo(tool, p.Command.ENABLE_OPERATION.value, 300)
    tool.network.sync.transmit()
    time.sleep(0.02)
    assert tool.sdo[p.TARGET_TORQUE].raw == 100 and drive.rpdos_discarded == 1


def test_drive_time_follows_the_wall_clock_without_sync_and_the_torque_stays(bus):
    # A real drive does not stop when SYNC stops; the old simulated drive only stepped on SYNC.
    tool, drive = bus()
    enable(tool, 200)
    start = drive.syncs
    time.sleep(0.4)
    periods = drive.syncs - start
    assert 0.7 * 0.4 / DT < periods < 1.1 * 0.4 / DT
    assert tool.sdo[p.CURRENT_ACTUAL].raw == pytest.approx(200, abs=3)


def test_tpdo1_carries_the_quantised_wrapping_position_and_the_torque_loop_current(bus):
    tool, drive = bus(encoder_offset_counts=2**31 - 1, torque_time_constant_s=2e-4)
    got = []
    tool.network.subscribe(0x180 + NODE, lambda cob, data, ts: got.append(bytes(data)))
    tool.sdo[p.MODES_OF_OPERATION].raw = p.MODE_CST
    tool.nmt.state = 'OPERATIONAL'
    tool.sdo[p.STATUSWORD].raw  # noqa: B018 - NMT taken
    tool.network.sync.transmit()
    time.sleep(0.05)
    statusword, counts, torque = struct.unpack('<Hih', got[-1][:8])
    q = float(drive.joint.plant.position_rad)
    assert counts == round(q / SCALING.rad_per_count) + 2**31 - 1 or counts < 0  # wraps
    assert p.decode_state(statusword) is p.State.SWITCH_ON_DISABLED


def test_reset_communication_restores_communication_objects_but_not_the_power_state(bus):
    tool, drive = bus()
    tool.sdo[p.HEARTBEAT_CONSUMER][1].raw = (127 << 16) | 100
    tool.sdo[p.SYNC_WINDOW_US].raw = 1500
    enable(tool, 150)
    booted = []
    tool.nmt.add_heartbeat_callback(booted.append)
    tool.nmt.state = 'RESET COMMUNICATION'
    time.sleep(0.1)
    assert 0 in booted  # the boot-up
    assert tool.sdo[p.HEARTBEAT_CONSUMER][1].raw == 0 and tool.sdo[p.SYNC_WINDOW_US].raw == 0
    assert p.decode_state(tool.sdo[p.STATUSWORD].raw) is p.State.OPERATION_ENABLED
    assert tool.sdo[p.TARGET_TORQUE].raw == 150


def test_a_fault_goes_through_fault_reaction_active_with_the_ramp(bus):
    tool, drive = bus(faults=FaultPlan('following_error', 0.3))  # 0.3 s after the first SYNC
    tool.sdo[p.TORQUE_SLOPE].raw = 1000  # 300 per mille: 0.3 s of ramp
    enable(tool, 300)
    tool.network.sync.transmit()
    assert p.decode_state(tool.sdo[p.STATUSWORD].raw) is p.State.OPERATION_ENABLED
    states = set()
    deadline = time.monotonic() + 2.0
    while time.monotonic() < deadline and p.State.FAULT not in states:
        states.add(p.decode_state(tool.sdo[p.STATUSWORD].raw))
    assert {p.State.FAULT_REACTION_ACTIVE, p.State.FAULT} <= states
    assert tool.sdo[p.ERROR_CODE].raw == 0x8611
    assert tool.sdo[p.DIGITAL_INPUTS].raw & (1 << 16)  # brake closed at the end


def test_error_frames_are_read_as_socketcan_codes_them():
    assert bus_error(error_frame('bus_off')) == 'CAN controller bus-off'
    assert bus_error(error_frame('error_passive')) == 'CAN controller error-passive'
    with pytest.raises(ValueError):
        error_frame('warning')


def test_the_hub_is_loopback_only_and_a_closed_hub_is_a_vanished_adapter():
    with pytest.raises(ValueError, match='loopback'):
        HubBus('10.0.0.1:1')
    hub = Hub().start()
    bus = HubBus(hub.address)
    hub.stop()
    import can

    with pytest.raises(can.CanOperationError, match='vanished|closed'):
        for _ in range(3):
            bus.recv(0.5)
    bus.shutdown()


def test_lab_and_deep_sea_drives_differ_by_the_oil():
    """The drive model takes the paper's two working conditions and refuses others."""
    deep, lab = plant_parameters('deep_sea'), plant_parameters('lab')
    assert deep.condition.pressure_pa == 10e6 and lab.condition.pressure_pa == 0.0
    with pytest.raises(ValueError, match='working_condition'):
        plant_parameters('moon')
