# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""CiA 402 master against the simulated drive on python-can's virtual bus (no ROS processes).

Enable, disable, fault and fault-reset sequences; the cycle's process data; injected faults
(over-current, following error, EMCY warning, dropped TPDOs, silent bus); OD checks.
"""

import itertools
import math
import time
from pathlib import Path

import canopen
import pytest

from actuator_cia402 import profile as p
from actuator_cia402.master import Cia402Error, Cia402Master
from actuator_cia402.scaling import Scaling
from actuator_cia402.sim_drive import FaultPlan, SimulatedDrive, plant_parameters


pytestmark = pytest.mark.realtime  # master and simulated drive paced by threads in real time

EDS = str(
    Path(__file__).resolve().parent.parent
    / 'src'
    / 'actuator_cia402'
    / 'eds'
    / 'sim_joint_drive.eds'
)
SCALING = Scaling(4096, 100.0, 1.05, 10.0, 0.105)
DT = 1e-3
NODE = 3
ENABLE = p.Command.ENABLE_OPERATION.value
_channels = itertools.count()


@pytest.fixture
def bus():
    """Provide a factory of (master, drive) on a fresh virtual bus.

    Both leave the bus at test end.
    """
    made = []

    def make(faults=FaultPlan(), scaling=SCALING, **drive_kwargs):
        """Return a drive and a master on their own virtual bus channel."""
        channel = f'test_cia402_{next(_channels)}'
        drive = SimulatedDrive(
            EDS, NODE, SCALING, DT, channel, faults=faults, **drive_kwargs
        ).start()
        network = canopen.Network()
        network.NOTIFIER_CYCLE = 0.05
        network.connect(interface='virtual', channel=channel, receive_own_messages=False)
        made.append((network, drive))
        master = Cia402Master(
            network, NODE, EDS, scaling, DT, 0x200 + NODE, 0x180 + NODE, 0x280 + NODE, 20.0
        )
        return master, drive

    yield make
    for network, drive in made:
        network.disconnect()
        drive.stop()


def run_cycles(master, n, current_a=0.0, controlword=ENABLE, wait_s=0.02):
    """Run n cycles with a constant command; return the feedbacks (None where TPDO1 missed)."""
    return [master.cycle(controlword, current_a, wait_s) for _ in range(n)]


def test_configure_maps_pdos_and_sets_cst_then_enable_and_disable_sequences(bus):
    """Configure maps PDOs (0x1600/0x1A00), sets 0x6060 = 10; activate enables.

    Deactivate quick-stops.
    """
    master, drive = bus()
    assert master.configure() == []
    assert drive.mode == p.MODE_CST and master.read_state()[1] is p.State.SWITCH_ON_DISABLED
    # the mapping is written over SDO; the drive takes it on NMT start
    assert not drive._pdo_ready
    assert int.from_bytes(drive.node.data_store[0x1A00][1], 'little') == 0x60410010
    master.activate()
    assert drive.state is p.State.OPERATION_ENABLED and drive.node.nmt.state == 'OPERATIONAL'
    assert [v.index for v in drive.node.rpdo[1].map] == [p.CONTROLWORD, p.TARGET_TORQUE]
    assert [v.index for v in drive.node.tpdo[1].map] == [
        p.STATUSWORD,
        p.POSITION_ACTUAL,
        p.TORQUE_ACTUAL,
    ]
    feedback = run_cycles(master, 5)
    assert all(f is not None for f in feedback)
    assert p.decode_state(feedback[-1].statusword) is p.State.OPERATION_ENABLED
    master.deactivate()
    assert (
        drive.state is p.State.SWITCH_ON_DISABLED
        and drive.brake
        and drive.node.nmt.state == 'PRE-OPERATIONAL'
    )
    assert not drive.gate.active


def test_enable_is_refused_without_cst_mode(bus):
    """The drive stays switched on when 0x6060 is not CST; activate says which state it reached."""
    master, drive = bus()
    master.configure()
    master._sdo(p.MODES_OF_OPERATION).raw = 0
    with pytest.raises(Cia402Error, match="did not reach 'operation enabled'"):
        master.activate()
    assert drive.state is p.State.SWITCHED_ON


def test_cycle_drives_the_joint_through_the_torque_loop_with_quantised_position(bus):
    """RPDO 0x6071 acts at the next SYNC through the first-order torque loop.

    0x6064 comes in whole counts.
    """
    master, drive = bus(torque_time_constant_s=2e-4)
    master.configure()
    master.activate()
    run_cycles(master, 1, 0.0)  # first command releases the brake
    assert not drive.brake
    fb = run_cycles(master, 1, 5.0)
    # SYNC k latches the RPDO; the current reaches 5 A (1 - exp(-dt/tau)) one period later.
    assert drive.current_a == pytest.approx(5.0 * (1 - math.exp(-DT / 2e-4)), rel=1e-6)
    fb += run_cycles(master, 300, 5.0)
    assert fb[-1].current_a == pytest.approx(5.0, abs=0.01) and fb[-1].torque_nm == pytest.approx(
        0.525, abs=1e-3
    )
    positions = [f.position_rad for f in fb if f is not None]
    assert positions[-1] > positions[0] + 1e-3  # 5 A lifts the joint against the 20 N m load
    for q in positions:
        assert abs(q / SCALING.rad_per_count - round(q / SCALING.rad_per_count)) < 1e-6


def test_after_a_missed_cycle_the_late_tpdo_of_the_previous_sync_is_not_taken_for_this_one(bus):
    """A TPDO1 arriving after its deadline.

    The next cycle takes the newest TPDO1, that of its own SYNC.
    """
    master, drive = bus()
    master.configure()
    master.activate()
    run_cycles(master, 100, 8.0)  # the joint moves: each TPDO1 has another angle
    assert master.cycle(ENABLE, 8.0, 0.0) is None  # deadline 0: the answer comes late
    feedback = master.cycle(ENABLE, 8.0, 0.02)
    assert feedback is not None and feedback.position_rad == SCALING.counts_to_rad(
        drive.last_tpdo_counts
    )
    assert (
        master.tpdo1_count == drive.syncs - drive.idle_periods
    )  # both answers arrived, the newest was used
    assert master.cycle(ENABLE, 8.0, 0.02) is not None  # and the next cycle waits for one again


def test_gate_of_the_drive_goes_to_zero_and_brake_when_rpdos_stop(bus):
    """SYNCs without RPDO beyond command_timeout_s.

    The drive's own gate applies 0 A and the brake.
    """
    master, drive = bus(command_timeout_s=0.005)
    master.configure()
    master.activate()
    run_cycles(master, 50, 3.0)
    assert drive.target_current_a == pytest.approx(3.0, abs=0.01) and not drive.brake
    for _ in range(10):  # SYNC without RPDO: 10 ms > 5 ms timeout
        master.network.sync.transmit()
        time.sleep(0.001)
    deadline = time.monotonic() + 2.0
    while drive.syncs < 60 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert drive.target_current_a == 0.0 and drive.brake and drive.gate.timeouts == 1


def test_a_late_sync_lets_the_skipped_periods_pass_for_the_joint(bus):
    """A master stall of 30 ms.

    The drive integrates the 30 periods (its watchdog applying 0 A and brake after 10 ms).
    """
    master, drive = bus()
    master.configure()
    master.activate()
    start = time.monotonic()
    for k in range(20):  # paced on the 1 ms grid
        master.cycle(ENABLE, 2.0, 0.01)
        time.sleep(max(0.0, start + (k + 1) * DT - time.monotonic()))
    assert drive.idle_periods <= 10 and not drive.brake  # paced: (almost) no catching up
    periods, idle = drive.syncs, drive.idle_periods
    time.sleep(0.030)
    master.cycle(ENABLE, 2.0, 0.01)
    assert drive.syncs - periods >= 30 and drive.idle_periods - idle >= 29
    assert drive.gate.timeouts == 1  # the stall outlasted command_timeout_s


@pytest.mark.parametrize(
    'kind, code, text',
    [
        ('over_current', 0x2310, 'continuous over-current'),
        ('following_error', 0x8611, 'following error'),
    ],
)
def test_injected_fault_mid_run_gives_the_error_code_then_fault_reset_recovers(
    bus, kind, code, text
):
    """Fault bit, EMCY and 0x603F carry the code.

    Activate resets the fault (controlword bit 7) and re-enables.
    """
    master, drive = bus(faults=FaultPlan(fault_kind=kind, fault_at_s=0.05))
    master.configure()
    master.activate()
    fb = run_cycles(master, 80, 2.0)
    assert master.fault is not None and master.fault.code == code and master.fault.text == text
    assert master.fault.source == 'emcy'  # the EMCY came before the TPDO with the fault bit
    assert drive.state is p.State.FAULT and drive.brake and drive.error_code == code
    assert p.decode_state(fb[-1].statusword) is p.State.FAULT and fb[-1].error_code == code
    assert master.read_error() == (code, text)
    master.deactivate()  # quick stop / disable are accepted in fault
    notes = master.activate()  # fault reset, then the enable sequence
    assert notes and f'0x{code:04X}' in notes[0] and 'fault reset' in notes[0]
    assert (
        drive.state is p.State.OPERATION_ENABLED and master.fault is None and drive.error_code == 0
    )
    fb = run_cycles(master, 5, 0.0)
    assert all(f is not None and not f.statusword & p.SW_FAULT for f in fb)


def test_real_over_current_faults_the_drive(bus):
    """A current above over_current_a faults the drive with 0x2310."""
    master, drive = bus(over_current_a=4.0)
    master.configure()
    master.activate()
    run_cycles(master, 20, 6.0)
    assert (
        master.fault is not None and master.fault.code == 0x2310 and drive.state is p.State.FAULT
    )


def test_emcy_without_error_register_is_a_warning_not_a_fault(bus):
    """An EMCY with error register 0 is kept as a warning; operation goes on."""
    master, drive = bus(faults=FaultPlan(emcy_code=0x4210, emcy_at_s=0.01))
    master.configure()
    master.activate()
    run_cycles(master, 30, 1.0)
    deadline = time.monotonic() + 1.0
    while not master.warnings and time.monotonic() < deadline:
        time.sleep(0.01)
    assert master.fault is None and drive.state is p.State.OPERATION_ENABLED
    assert (
        master.warnings and '0x4210' in master.warnings[0] and 'temperature' in master.warnings[0]
    )


def test_dropped_tpdos_are_missed_cycles_not_faults(bus):
    """Each dropped TPDO1 is one missed cycle (None), nothing more."""
    master, drive = bus(faults=FaultPlan(drop_tpdo_fraction=0.3, seed=7))
    master.configure()
    master.activate()
    fb = run_cycles(master, 200, 0.0, wait_s=0.005)
    missed = sum(f is None for f in fb)
    assert 30 <= drive.tpdos_dropped <= 90  # seeded: the same draws every run
    # every drop is a miss; a few more when other jobs starve this process for the 5 ms deadline
    assert drive.tpdos_dropped <= missed <= drive.tpdos_dropped + 10
    assert master.fault is None


def test_silent_bus_gives_no_feedback_and_no_sdo_answer(bus):
    """From silent_at_s on: no TPDO, and SDO times out."""
    master, drive = bus(faults=FaultPlan(silent_at_s=0.02))
    master.configure()
    master.activate()
    fb = run_cycles(master, 40, 0.0, wait_s=0.005)
    assert all(f is not None for f in fb[:15]) and all(f is None for f in fb[25:])
    assert drive.silent
    with pytest.raises(canopen.SdoCommunicationError):
        master.read_state()


def test_configure_refuses_a_drive_that_does_not_match_the_parameters(bus):
    """0x6075 or 0x608F differing from the parameters: configure refuses, naming both values."""
    master, _ = bus(scaling=Scaling(4096, 100.0, 1.05, 8.0, 0.105))
    with pytest.raises(Cia402Error, match='rated current 0x6075 .* 10000 mA, configured 8000 mA'):
        master.configure()
    master, _ = bus(scaling=Scaling(16384, 100.0, 1.05, 10.0, 0.105))
    with pytest.raises(Cia402Error, match='encoder resolution'):
        master.configure()


def test_configure_without_a_drive_says_so(bus):
    """No SDO answer at all: configure says the node does not answer."""
    master, drive = bus(faults=FaultPlan(silent_at_s=0.0))
    drive.silent = True
    with pytest.raises(Cia402Error, match='does not answer SDO'):
        master.configure()


def test_lab_and_deep_sea_drives_differ_by_the_oil():
    """The drive model takes the paper's two working conditions and refuses others."""
    deep, lab = plant_parameters('deep_sea'), plant_parameters('lab')
    assert deep.condition.pressure_pa == 10e6 and lab.condition.pressure_pa == 0.0
    with pytest.raises(ValueError, match='working_condition'):
        plant_parameters('moon')
