# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Real-drive hazards (issue 20): the simulated drive in its own process, the joint against it.

Every test starts ``cia402_sim_drive`` (``python -m actuator_cia402.sim_drive_main``) as a
process with its CAN hub on 127.0.0.1, and stops it at the end (the fixture). The joint runs in
this process, or in ``cia402_torque_test`` when the test kills the master. Each comment says
what the driver before issue 20 did, so why the test would fail on it. SYNC at 500 Hz, so the
shared 2-core machine keeps the grid.
"""

from __future__ import annotations

import contextlib
import re
import signal
import sys
import threading
import time

import canopen
import numpy as np
import pytest

from actuator_bringup.supervisor import RosProcess
from actuator_cia402 import profile as p
from actuator_cia402.config import DriverParameters
from actuator_cia402.hub import HubBus
from actuator_cia402.joint import Cia402Joint
from actuator_cia402.sim_drive_main import default_eds
from actuator_cia402.torque_test import run_on_grid
from actuator_core.joint import JointError
from host_probe import skip_or_fail

pytestmark = pytest.mark.ros  # processes: the simulated drive (and a killed master)
PERIOD_S = 0.002


@pytest.fixture
def sim_drive(tmp_path):
    """Start simulated drive process with extra arguments; all stopped at the end."""
    started = []

    def start(*args, ids=(1,)):
        cmd = [
            sys.executable,
            '-m',
            'actuator_cia402.sim_drive_main',
            '--sync-period',
            str(PERIOD_S),
            *[f'--node-id={i}' for i in ids],
            *args,
        ]
        proc = RosProcess(cmd, log_dir=tmp_path, name=f'sim_drive_{len(started)}')
        started.append(proc)
        for i in ids:
            proc.wait_for_output(rf'^drive {i} ready$', timeout=30)
        proc.address = re.search(r'bus hub on (\S+)', proc.stdout).group(1)
        return proc

    yield start
    for proc in started:
        proc.stop()
        assert not proc.running


@pytest.fixture
def tool():
    """Connect a service tool on the hub (SDO only, no heartbeat), as a person's PC would be."""
    networks = []

    def connect(address, node_id=1):
        network = canopen.Network(HubBus(address))
        network.NOTIFIER_CYCLE = 0.1
        network.connect()
        networks.append(network)
        node = canopen.RemoteNode(node_id, default_eds())
        network.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 1.0
        return node

    yield connect
    for network in networks:
        network.disconnect()


def joint_for(drive, **overrides) -> Cia402Joint:
    """Return a joint on the drive's hub with the test's SYNC period.

    The drive process here can stall for 50 ms at load 5 (seen once): silence ends control only
    after 0.25 s in these tests.
    """
    overrides.setdefault('feedback_timeout_s', 0.25)
    cfg = DriverParameters(
        interface='hub',
        channel=drive.address,
        simulated_drive=True,
        sync_period_s=PERIOD_S,
        **overrides,
    )
    return Cia402Joint(cfg)


def producer_and_consumer(drive) -> tuple[Cia402Joint, Cia402Joint]:
    """Joints 1 (SYNC producer, master 127) and 2 (consumer, master 126) on the drive's bus.

    A stall of this process's threads must not trip the drives' heartbeat consumers: 0.5 s.
    """
    a = joint_for(drive, node_id=1, master_node_id=127, heartbeat_timeout_s=0.5)
    b = joint_for(
        drive, node_id=2, master_node_id=126, sync_producer=False, heartbeat_timeout_s=0.5
    )
    return a, b


def run_pair(
    producer: Cia402Joint,
    consumer: Cia402Joint,
    current_a: float,
    producer_s: float,
    consumer_s: float,
    producer_delay_s: float = 0.0,
) -> dict:
    """Activate both, run the consumer on a thread and the producer here (after a delay).

    Each brakes 50 ms, then holds ``current_a``; returns run_on_grid's results as 'a'
    (producer) and 'b' (consumer), once the consumer has ended too.
    """
    results = {}
    with active(producer, consumer):
        thread = threading.Thread(
            target=lambda: results.update(
                b=run_on_grid(consumer, current_a, 0.05, consumer_s, PERIOD_S)
            )
        )
        thread.start()
        time.sleep(producer_delay_s)
        results['a'] = run_on_grid(producer, current_a, 0.05, producer_s, PERIOD_S)
        thread.join(10)
    return results


@contextlib.contextmanager
def active(*joints: Cia402Joint):
    """Configure and activate ``joints`` in turn; close them in that same order at the end.

    They are closed whatever happened, after a failed configure or activate too.
    """
    try:
        for joint in joints:
            joint.configure()
            joint.activate()
        yield
    finally:
        for joint in joints:
            joint.close()


def wait_until(condition, timeout_s: float, what: str):
    """Poll ``condition`` until true; fail with ``what``."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f'{what} within {timeout_s} s')
        time.sleep(0.01)


def state_of(node) -> p.State:
    """Read the drive's state over SDO; the two clients of the one SDO channel take turns."""
    time.sleep(0.05)
    state = p.decode_state(node.sdo[p.STATUSWORD].raw)
    time.sleep(0.05)
    return state


def current_of(node) -> float:
    """Read the drive's current actual over SDO [A] (rated current 10 A = 1000 per mille)."""
    time.sleep(0.05)
    current = node.sdo[p.CURRENT_ACTUAL].raw / 100.0
    time.sleep(0.05)
    return current


def test_without_a_heartbeat_consumer_the_drive_keeps_its_last_torque(sim_drive, tool):
    # The hazard itself, as the old driver left it: enabled over SDO, no 0x1016, then the
    # master goes silent. A real CST drive keeps the torque; the old simulated drive's own RPDO
    # watchdog hid this (it went to 0 A after 10 ms).
    drive = sim_drive()
    node = tool(drive.address)
    node.sdo[p.MODES_OF_OPERATION].raw = p.MODE_CST
    for command in p.ENABLE_SEQUENCE:
        node.sdo[p.CONTROLWORD].raw = command.value
    node.sdo[p.TARGET_TORQUE].raw = 100  # 1 A
    time.sleep(0.5)
    assert state_of(node) is p.State.OPERATION_ENABLED
    assert current_of(node) == pytest.approx(1.0, abs=0.02)


def test_kill_9_of_the_master_under_torque_stops_the_drive_by_its_heartbeat_consumer(
    sim_drive, tool, tmp_path
):
    # Old driver: no heartbeat consumer on the drive, no master heartbeat; after SIGKILL the
    # drive kept its target torque (the test above), so 'quick stop active' never came.
    drive = sim_drive('--no-load')  # a free joint: the tool's sign check needs one
    master = RosProcess(
        [
            sys.executable,
            '-m',
            'actuator_cia402.torque_test',
            '--interface',
            'hub',
            '--channel',
            drive.address,
            '--simulated',
            '--current',
            '1.0',
            '--velocity-limit',
            '20',  # 1 A runs the joint beyond the tool's default 1 rad/s within the minute
            '--duration',
            '60',
            '--sync-period',
            str(PERIOD_S),
        ],
        log_dir=tmp_path,
        name='torque_test',
    )
    try:
        master.wait_for_output(r'applying 1 A', timeout=30)
        node = tool(drive.address)
        assert state_of(node) is p.State.OPERATION_ENABLED
        assert current_of(node) == pytest.approx(1.0, abs=0.05)
        assert node.sdo[p.HEARTBEAT_CONSUMER][1].raw == (127 << 16) | 300
        assert node.sdo[p.ABORT_CONNECTION_OPTION].raw == 3
        killed = time.monotonic()
        master.popen.send_signal(signal.SIGKILL)
        master.popen.wait(5)
        wait_until(
            lambda: (
                'brake closed' in drive.stdout.split('heartbeat')[-1]
                and 'heartbeat of node 127 lost' in drive.stdout
            ),
            5.0,
            'the drive did not stop by its heartbeat consumer',
        )
        stopped_s = time.monotonic() - killed
        assert state_of(node) is p.State.SWITCH_ON_DISABLED  # 0x605A = 2: it disables itself
        assert current_of(node) == 0.0
        assert node.sdo[p.DIGITAL_INPUTS].raw & (1 << 16)  # brake closed
        # heartbeat 300 ms + ramp 10 ms + brake 20 ms, plus the polling of this test
        assert stopped_s < 1.0
    finally:
        master.stop()


def test_enable_with_a_stale_target_torque_applies_only_the_first_command(sim_drive, tool):
    # Old driver: enabled operation over SDO while 0x6071 still held 800 per mille (a value a
    # previous run left), before any SYNC; the drive applied 800 per mille at once.
    drive = sim_drive()
    node = tool(drive.address)
    node.sdo[p.TARGET_TORQUE].raw = 800
    joint = joint_for(drive)
    try:
        joint.configure()
        time.sleep(0.1)  # one SDO channel, two clients: the joint's answers must be gone first
        assert node.sdo[p.TARGET_TORQUE].raw == 0
        node.sdo[p.TARGET_TORQUE].raw = 800  # left again between configure and activate
        time.sleep(0.1)  # one SDO channel, two clients: the tool's answer must be gone first
        joint.activate()
        result = run_on_grid(joint, 0.5, 0.2, 0.2, PERIOD_S)
        assert result['fault'] == ''
        joint.deactivate()
    finally:
        joint.close()
    enables = re.findall(r'operation enabled with 0x6071 = (-?\d+)', drive.stdout)
    assert enables == ['50']  # the first command, 0.5 A; the brake was released once
    assert drive.stdout.count('brake released') == 1


def test_configure_makes_a_drive_left_enabled_safe_with_ramp_and_brake(sim_drive, tool):
    # Old driver: configure went to pre-operational and mapped PDOs; a drive left enabled by a
    # crashed master stayed enabled, applying its 0x6071.
    drive = sim_drive('--left-enabled', '300')
    node = tool(drive.address)
    time.sleep(0.1)
    assert current_of(node) == pytest.approx(3.0, abs=0.05)  # the hazard is there
    joint = joint_for(drive)
    try:
        notes = joint.configure()
        assert any('left operation enabled' in n for n in notes), notes
        assert state_of(node) is p.State.SWITCH_ON_DISABLED
        assert current_of(node) == 0.0
        assert node.sdo[p.DIGITAL_INPUTS].raw & (1 << 16)
    finally:
        joint.close()
    log = drive.stdout
    assert 'stopping: ramp from 300 per mille' in log
    assert log.index('brake closed') < log.index('stopped: ')
    assert 'ramp cut' not in log and 'voltage disabled with the brake open' not in log


def test_deactivate_waits_for_the_quick_stop_ramp_and_the_brake_before_disable(sim_drive, tool):
    # Old driver: quick stop, then disable voltage 1 ms later, cutting the drive's ramp; the
    # simulated drive reports that as 'ramp cut' (shown first, with the old sequence by SDO).
    drive = sim_drive()
    node = tool(drive.address)
    node.sdo[p.MODES_OF_OPERATION].raw = p.MODE_CST
    node.sdo[p.TORQUE_SLOPE].raw = 1000
    for command in p.ENABLE_SEQUENCE:
        node.sdo[p.CONTROLWORD].raw = command.value
    node.sdo[p.TARGET_TORQUE].raw = 300
    time.sleep(0.05)
    node.sdo[p.CONTROLWORD].raw = p.Command.QUICK_STOP.value
    node.sdo[p.CONTROLWORD].raw = p.Command.DISABLE_VOLTAGE.value
    wait_until(lambda: 'ramp cut' in drive.stdout, 2.0, 'the old sequence was not seen to cut')
    joint = joint_for(drive, torque_slope_permille_s=5000)
    with active(joint):
        result = run_on_grid(joint, 3.0, 0.05, 0.3, PERIOD_S)
        assert result['fault'] == ''
        start = time.monotonic()
        notes = joint.deactivate()
        took_s = time.monotonic() - start
        assert notes == []
    tail = drive.stdout.split('NMT reset communication')[-1]
    assert 'ramp cut' not in tail and 'voltage disabled with the brake open' not in tail
    # Since issue 44 deactivate first runs braked cycles: the drive takes 0 A at the next SYNC
    # (its disable-operation ramp starts from the 0 A latched with it), then closes the brake.
    stop = tail.index('stopping: ramp from 0 per mille (option 1)')
    assert stop < tail.index('brake closed', stop) < tail.index('stopped: switched on')
    assert took_s >= 0.02  # the brake's 20 ms before disable voltage


def test_deactivate_after_the_last_cycles_brake_ends_with_the_voltage_disabled(sim_drive, tool):
    # The joint node's own stop: its last cycle wrote 0 A with the brake (disable operation, whose
    # ramp and brake the drive then runs), so deactivate's quick stop finds the drive still in
    # 'operation enabled'; the drive ends that reaction in 'switched on'. Before, the master
    # waited 1 s for 'quick stop active', gave up with a note and left the drive switched on
    # (voltage on, NMT operational): seen at every driver stop of the adversarial runs.
    drive = sim_drive()
    joint = joint_for(drive)
    with active(joint):
        result = run_on_grid(joint, 3.0, 0.05, 0.3, PERIOD_S)
        assert result['fault'] == ''
        joint.write(0.0, True)
        joint.read(0)  # the cycle's SYNC: the drive latches the brake (disable operation)
        start = time.monotonic()
        notes = joint.deactivate()
        took_s = time.monotonic() - start
        state = state_of(tool(drive.address))
    assert notes == [], notes
    assert state is p.State.SWITCH_ON_DISABLED
    assert took_s < 0.5, took_s  # the ramp and the brake's 20 ms, not a state timeout
    tail = drive.stdout.split('NMT reset communication')[-1]
    assert 'stopped: switched on' in tail and 'voltage disabled with the brake open' not in tail


@pytest.mark.parametrize(
    'kind, words',
    [
        ('sto', 'operation left without a fault'),
        ('quick_stop_input', 'quick stop active'),
        ('remote_off', 'remote off'),
        ('target_ignored', 'ignores the target torque'),
        ('bus_off', 'bus-off'),
        ('error_passive', 'error-passive'),
    ],
)
def test_every_reason_not_to_apply_the_torque_ends_control_with_it(sim_drive, kind, words):
    # Old driver: only the statusword fault bit (and EMCY) ended the cycle; STO, a quick-stop
    # input, remote off, bit 12 and bus errors went unnoticed while the controller kept
    # commanding.
    drive = sim_drive('--inject', f'{kind}@1.0')
    joint = joint_for(drive)
    with active(joint):
        result = run_on_grid(joint, 0.5, 0.1, 5.0, PERIOD_S)
    assert words in result['fault'], result['fault']


def test_a_vanished_adapter_ends_control_at_once(sim_drive):
    # Old driver: a silent bus was noticed after the 50 ms feedback timeout; a closed adapter
    # was not told apart from a silent drive.
    drive = sim_drive()
    joint = joint_for(drive)
    seen = {}
    with active(joint):

        def on_sample(k, sample):
            if k >= 100 and 'killed' not in seen:
                drive.popen.send_signal(signal.SIGKILL)
                seen['killed'] = time.monotonic()
            if sample.fault and 'ended' not in seen:
                seen['ended'] = time.monotonic()

        result = run_on_grid(joint, 0.2, 0.05, 5.0, PERIOD_S, on_sample)
    assert 'CAN adapter lost' in result['fault']
    assert seen['ended'] - seen['killed'] < 0.1


def test_a_drive_fault_is_never_reset_by_activate_only_by_acknowledge_fault(sim_drive, tool):
    # Old driver: every activate reset a drive fault without asking anyone.
    drive = sim_drive('--fault-kind', 'over_current', '--fault-at', '1.0')
    node = tool(drive.address)
    joint = joint_for(drive)
    with active(joint):
        result = run_on_grid(joint, 0.5, 0.1, 5.0, PERIOD_S)
        assert 'drive fault' in result['fault'] and '0x2310' in result['fault']
        joint.deactivate()
        with pytest.raises(JointError, match='acknowledge'):
            joint.activate()
        assert state_of(node) is p.State.FAULT
        assert 'acknowledged' in joint.acknowledge_fault()
        assert state_of(node) is p.State.SWITCH_ON_DISABLED
        joint.activate()
        assert state_of(node) is p.State.SWITCHED_ON


def test_the_32_bit_position_is_unwrapped_and_the_zero_offset_applied(sim_drive):
    # Old driver: counts_to_rad of the raw INTEGER32; crossing 2^31 jumped by 2^32 counts
    # (65 536 rad here). The drive's counter starts 30 counts below the wrap.
    drive = sim_drive('--encoder-offset-counts', str(2**31 - 30), '--working-condition', 'lab')
    count_rad = joint_for(drive).scaling.rad_per_count
    joint = joint_for(drive, zero_offset_rad=(2**31 - 30) * count_rad)
    with active(joint):
        result = run_on_grid(joint, 3.0, 0.05, 0.5, PERIOD_S)
    q = result['positions']
    assert result['fault'] == ''
    assert abs(q[0]) < 1e-9  # the zero offset
    assert joint.unwrap.wraps == 1
    assert max(abs(b - a) for a, b in zip(q, q[1:])) < 0.5  # a wrap would be 65 536 rad
    assert max(q) > 30 * count_rad  # it did cross


def test_configure_writes_and_verifies_the_watchdog_sync_window_and_limits(sim_drive, tool):
    # Old driver: none of these objects was written; 0x6072 was only compared.
    drive = sim_drive()
    node = tool(drive.address)
    joint = joint_for(drive)
    try:
        joint.configure()
        time.sleep(0.1)  # one SDO channel, two clients: the joint's answers must be gone first
        assert node.sdo[p.SYNC_WINDOW_US].raw == 4000  # 2 periods of 2 ms
        assert node.sdo[p.COMMUNICATION_CYCLE_US].raw == 2000
        assert (
            node.sdo[p.INTERPOLATION_PERIOD][1].raw,
            node.sdo[p.INTERPOLATION_PERIOD][2].raw,
        ) == (2, -3)
        assert node.sdo[p.MAX_TORQUE].raw == 2000  # 20 A of the 10 A rated
        assert node.sdo[p.MAX_CURRENT].raw == 2000
        assert node.sdo[p.QUICK_STOP_OPTION].raw == 2  # no transition 16 (issue 44)
        assert node.sdo[p.DISABLE_OPERATION_OPTION].raw == 1
        # 100 rad/s^2 at the joint (the simulated default) as motor rpm/s through N = 100
        assert node.sdo[p.QUICK_STOP_DECELERATION].raw == 95493
        assert node.sdo[p.HEARTBEAT_PRODUCER_MS].raw == 100  # consumed by the master
    finally:
        joint.close()


@pytest.mark.parametrize(
    'args, overrides, words',
    [
        (('--polarity', '128'), {}, 'polarity 0x607E'),
        ((), {'node_id': 2}, 'no boot-up'),
        ((), {'encoder_counts_per_rev': 1024}, 'encoder resolution'),
    ],
)
def test_configure_refuses_a_drive_that_differs_from_the_parameters(
    sim_drive, args, overrides, words
):
    # Old driver: polarity and boot-up were never checked.
    drive = sim_drive(*args)
    joint = joint_for(drive, state_timeout_s=0.3, sdo_timeout_s=0.1, **overrides)
    with pytest.raises(JointError, match=re.escape(words)):
        joint.configure()
    joint.close()


def test_an_eds_of_another_product_is_refused(sim_drive, tmp_path):
    drive = sim_drive()
    eds = tmp_path / 'other.eds'
    eds.write_text(
        open(default_eds()).read().replace('ProductNumber=0x00000402', 'ProductNumber=0x00000999')
    )
    cfg = DriverParameters(
        interface='hub', channel=drive.address, eds_file=str(eds), sync_period_s=PERIOD_S
    )
    joint = Cia402Joint(cfg)
    with pytest.raises(JointError, match='identity 0x1018'):
        joint.configure()
    joint.close()


@pytest.mark.realtime  # the samples each joint took on its grid: judged with the host probe
def test_two_joints_share_one_sync_producer(sim_drive, host_window):
    drive = sim_drive(ids=(1, 2))
    a, b = producer_and_consumer(drive)
    results = run_pair(a, b, 0.3, 1.0, 1.0)
    drive.stop()
    syncs = [int(n) for n in re.findall(r'drive \d: SYNCs (\d+)', drive.stdout)]
    # one SYNC stream seen by both drives (a drive's bus thread may lag a few frames at exit)
    assert len(syncs) == 2 and min(syncs) > 0.9 * max(syncs)
    assert results['a']['fault'] == results['b']['fault'] == ''
    # one SYNC per cycle of the producer (plus none from b): not two producers
    assert max(syncs) <= a.cycles + 5
    # both joints in this one process with their bus threads, on a shared 2-core machine:
    # measured 338 and 408 of 525 cycles at load 3 (the drive process serves both drives), 192
    # on a loaded CI host
    bound = 0.5 * 1.05 / PERIOD_S
    short = {k: r['samples'] for k, r in results.items() if r['samples'] <= bound}
    if short:
        skip_or_fail(
            host_window,
            f'samples taken {short} of {1.05 / PERIOD_S:.0f} cycles (bound {bound:.0f})',
            samples=sum(bound - n for n in short.values()),
        )


def test_a_sync_consumer_waits_for_a_late_producer_and_stops_on_a_silent_one(sim_drive):
    """Joint 2 (SYNC consumer) starts before joint 1's driver sends SYNC: no fault meanwhile.

    Old driver: every cycle before the producer's first SYNC counted as a missed TPDO, and the
    consumer ended control 50 ms after it started ('no TPDO from the drive in 51 cycles'), the
    first time two joints were run from bringup. Once the producer stops, the consumer ends
    control after feedback_timeout_s, naming the SYNC; with no producer at all, after
    first_sync_timeout_s.
    """
    drive = sim_drive(ids=(1, 2))
    a, b = producer_and_consumer(drive)
    # the producer starts 0.4 s later (400 cycles without SYNC) and stops before the consumer
    results = run_pair(a, b, 0.0, 0.5, 3.0, producer_delay_s=0.4)
    assert results['a']['fault'] == ''
    assert "no SYNC from the bus's producer in" in results['b']['fault'], results['b']
    assert 'since activation' not in results['b']['fault']  # it had SYNCs, then none
    assert results['b']['samples'] > 0.3 * 0.5 / PERIOD_S, results['b']
    alone = joint_for(
        drive,
        node_id=2,
        master_node_id=126,
        sync_producer=False,
        first_sync_timeout_s=0.2,
    )
    with active(alone):
        started = time.monotonic()
        result = run_on_grid(alone, 0.0, 0.05, 2.0, PERIOD_S)
        waited = time.monotonic() - started
    drive.stop()
    assert result['samples'] == 0
    assert "no SYNC from the bus's producer in" in result['fault']
    assert 'since activation' in result['fault'] and 0.2 <= waited < 2.0, (result, waited)


def test_with_the_polarity_both_sides_agree_on_a_positive_current_turns_positive(sim_drive):
    # Old driver: 0x607E was never read; an inverted drive ran the loop with positive feedback.
    drive = sim_drive('--polarity', '128', '--working-condition', 'lab')
    joint = joint_for(drive, polarity=128)
    with active(joint):
        result = run_on_grid(joint, 3.0, 0.05, 0.3, PERIOD_S)
    assert result['fault'] == ''
    assert result['positions'][-1] - result['positions'][0] > 0.01
    efforts = result['efforts']  # torque actual, the sign corrected by the drive's polarity
    assert min(efforts) >= 0 and max(efforts) == pytest.approx(3.0 * 0.105 * 100, rel=0.01)


def test_late_and_dropped_answers_never_give_a_sample_another_syncs_position(sim_drive):
    # Before: after a cycle without TPDO1 in time, a lone TPDO1 in the next cycle was taken as
    # that cycle's answer. When it was the late answer of the SYNC before, the sample carried a
    # position one period old: the implied velocity halved, then doubled, and the observer
    # refused the step and restarted (the end-to-end loop reached 2.5e-2 rad, 2026-12-05).
    # Late answers here come with the next SYNC's; two in a row were the failing case.
    drive = sim_drive('--late-tpdo', '0.1', '--drop-tpdo', '0.03', '--seed', '7')
    joint = joint_for(drive)
    samples = []
    try:
        joint.configure()
        joint.activate()
        result = run_on_grid(  # 8 A: the joint runs at about 10 rad/s
            joint,
            8.0,
            0.05,
            0.5,
            PERIOD_S,
            on_sample=lambda k, s: samples.append((s.stamp_ns, s.position_rad)),
        )
        joint.deactivate()
    finally:
        joint.close()
    drive.stop()
    dropped, late = (
        int(n) for n in re.search(r'TPDOs dropped (\d+), late (\d+)', drive.stdout).groups()
    )
    assert result['fault'] == '' and late > 10 and dropped > 2, (result['fault'], drive.stdout)
    stamps, positions = (np.array(c, dtype=float) for c in zip(*samples))
    t_s = stamps * 1e-9
    velocity = np.diff(positions) / np.diff(t_s)  # rad/s over each stamp gap
    acceleration = np.diff(velocity) / np.diff(0.5 * (t_s[1:] + t_s[:-1]))
    # 8 A takes the joint to about 10 rad/s at up to 170 rad/s^2; a sample one period old
    # changes the implied velocity by the velocity itself within a period: about 5000 rad/s^2
    moving = velocity[1:] > 1.0
    assert moving.sum() > 100, velocity
    assert np.max(np.abs(acceleration[moving])) < 1000.0, np.sort(np.abs(acceleration))[-5:]
    assert joint.answers.dropped <= dropped
