# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""CiA 402 driver node in real time (ROS-PROCESS TESTS: each starts installed executables).

Closed loops through the driver and the simulated drive at 1 kHz, each process as
``graph.closed_loop`` starts it (what ``bringup --joint cia402_sim`` starts): a silent or faulted
drive against the real controller, kill -9 of the driver, the end-to-end run of the paper's fast
deep-sea case; and a second publisher on current_command against the driver. The driver's other
tests: tests/test_cia402_nodes.py; the shared pieces in tests/cia402_helpers.py.
"""

import os
import re
import signal
import time

import numpy as np
import pytest

from actuator_cia402.config import DriverParameters
from actuator_core import limits
from cia402_helpers import DRIVER, driver_args, harness_fixture, sim_drive_fixture, wait_for_output  # noqa: F401 - fixtures by name
from host_probe import CIA402_LOOP, fifo_granted, require_speed, skip_or_fail
from ros_helpers import start_closed_loop

#: SCHED_FIFO priority of the ESO and controller in the closed loops through the drive (driver
#: one above, simulated drive one above that: graph.closed_loop), as in test_adversarial. Under
#: normal scheduling on a 2-core VM the loop through the drive kept 43-96 % of the 1 kHz grid and
#: ran away to the 20 rad/s soft limit in 0.2-1.6 s (issue 20); under SCHED_FIFO 99.6-99.9 % of
#: SYNCs had a command, median lag 1 ms.
CLOSED_LOOP_PRIORITY = 50
#: Tracking of the 5 s end-to-end run through the drive on [1, 5) s, as measured
#: (docs/cia402.md#tuned-for-the-drives-delay): the largest max |e| and RMS [rad] of three runs
#: without a stall.
END_TO_END_MAX_RAD, END_TO_END_RMS_RAD = 2.28e-3, 7.62e-4


#: Fraction of the commands the driver may refuse as too late (stamp outside its window) for a
#: run to count as one the machine kept on time: such runs had a command on 99.6-99.9 % of the
#: SYNCs; on a host about 1.4x slower (2026-12-02) the runs refused 19-25 % and ran away to the
#: 20 rad/s soft limit, which the driver ended safely.
LATE_COMMANDS_MAX = 0.02
#: Share of the commands applied a SYNC or more later than the one SYNC the drive tuning is
#: designed for, above which a run shows the host, not the loop: 2026-12-05, the runs here with
#: 2-20 % kept the bounds; of four with 30-40 %, two swung at +-20 A to 1.6e-2 and 2.5e-2 rad.
DELAYED_COMMANDS_MAX = 0.25


def _late_commands(driver_log: str) -> float | None:
    """Fraction of samples whose command the driver refused by stamp (its summary line)."""
    match = re.search(
        r'stopped at sample (\d+); refused commands \d+ by value and (\d+) by stamp', driver_log
    )
    if match is None or int(match.group(1)) == 0:
        return None
    return int(match.group(2)) / int(match.group(1))


def _closed_loop(ros_process, tmp_path, driver_params, record=True, watchers=0):
    """Return the run as graph.closed_loop describes it with the driver as the joint.

    What bringup --joint cia402_sim starts. ``watchers``: the test's own subscriptions on
    joint_states, which the driver's start condition counts as well: without them a test
    subscription could stand in for a loop node not yet discovered (the ESO then saw no
    measurement in a run whose fault came before its discovery, and the loop never started).
    """
    from actuator_bringup.run_description import closed_loop, default_scenario
    from actuator_bringup.runner import scenario_file

    params = dict(driver_params)
    specs = closed_loop(
        'realtime',
        float(params.pop('stop_after_s', 0.0)),
        record=record,
        bag=tmp_path / 'bag',
        joint='cia402_sim',
        thread_priority=CLOSED_LOOP_PRIORITY,
        joint_parameters=params,
    )
    for spec in specs:
        if spec.key == 'driver':
            spec.parameters['wait_for_subscribers'] += watchers

    def drive_ready(key, proc) -> None:
        if key == 'drive':  # the simulated drive: listening before the driver configures
            proc.wait_for_output(r'^drive 1 ready$', timeout=30)

    return start_closed_loop(
        ros_process,
        specs,
        scenario_file(default_scenario('cia402_sim')),
        extra={'driver': ['-p', f'timing_log:={tmp_path / "samples.npz"}']},
        on_start=drive_ready,
    )


# A closed loop through the drive at 1 kHz: its timing is the machine's (one rerun, as for
# every realtime-marked test; see conftest).
@pytest.mark.realtime
@pytest.mark.parametrize(
    'fault, driver_says',
    [
        # the fault plan's clock starts with the first SYNC: under control by then
        ({'sim.silent_at_s': 0.5}, r'CiA 402 drive fault: no TPDO from the drive in'),
        (
            {'sim.fault_kind': 'following_error', 'sim.fault_at_s': 1.5},
            r'CiA 402 drive fault: drive fault .*0x8611 following error',
        ),
    ],
)
def test_silent_or_faulted_drive_gives_the_stale_measurement_stop_of_the_controller(
    harness, ros_process, tmp_path, fault, driver_says
):
    """Silent or faulted drive in closed loop: the controller commands 0 A with safe_stop."""
    procs = _closed_loop(ros_process, tmp_path, fault, record=False, watchers=1)
    wait_for_output(procs['driver'], driver_says, timeout=40)
    harness.command.clear()
    try:
        harness.wait_for(
            lambda: any(c.safe_stop for c in harness.command),
            timeout=20,
            what='a safe-stop command',
        )
    except AssertionError as timed_out:  # what each process said, for the next person
        said = '\n'.join(procs[key].describe(tail=15) for key in ('driver', 'controller'))
        raise AssertionError(f'{timed_out}\n{said}') from None
    harness.command.clear()
    harness.spin(0.5)
    assert harness.command, 'the controller keeps commanding while stale'
    assert all(c.current_a == 0.0 and c.safe_stop for c in harness.command)
    assert 'stale measurement' in procs['controller'].output
    for key, proc in procs.items():
        code = proc.stop()
        assert code == 0 and 'Traceback' not in proc.output, (key, proc.output[-1500:])


# A closed loop through the drive at 1 kHz: its timing is the machine's (one rerun, as for
# every realtime-marked test; see conftest).
@pytest.mark.realtime
def test_kill_9_of_the_driver_in_closed_loop_leaves_the_drive_to_stop_itself(
    ros_process, tmp_path
):
    """The drive runs on after SIGKILL of its master and quick-stops by its heartbeat consumer.

    Before issue 20 the drive was a thread of the driver (it died with it) and, on a real bus,
    kept its last torque: no heartbeat consumer, no master heartbeat.
    """
    procs = _closed_loop(ros_process, tmp_path, {}, record=False)
    wait_for_output(procs['drive'], r'operation enabled with 0x6071', timeout=40)
    time.sleep(1.0)  # under control of the controller
    procs['driver'].popen.send_signal(signal.SIGKILL)
    wait_for_output(procs['drive'], r'heartbeat of node 127 lost for 300 ms', timeout=5)
    time.sleep(0.5)  # the quick-stop ramp and the brake's closing time
    import canopen

    from actuator_cia402 import profile as p
    from actuator_cia402.hub import HubBus
    from actuator_cia402.sim_drive_main import default_eds

    address = re.search(r'bus hub on (\S+)', procs['drive'].stdout).group(1)
    network = canopen.Network(HubBus(address))
    network.connect()
    try:  # a service tool on the bus: the drive stopped itself
        tool = canopen.RemoteNode(1, default_eds())
        network.add_node(tool)
        state = p.decode_state(tool.sdo[p.STATUSWORD].raw)
        assert state in (p.State.QUICK_STOP_ACTIVE, p.State.SWITCH_ON_DISABLED), state
        assert tool.sdo[p.CURRENT_ACTUAL].raw == 0
        assert tool.sdo[p.DIGITAL_INPUTS].raw & (1 << 16)  # brake closed
    finally:
        network.disconnect()
    assert procs['drive'].running
    for key in ('eso', 'controller', 'drive'):
        assert procs[key].stop() == 0, procs[key].describe()


@pytest.mark.realtime
def test_end_to_end_fast_deep_sea_case_tracks_within_a_factor_of_the_offline_core(
    ros_process, tmp_path, host_window
):
    """Real time, separate processes.

    The drive adds quantisation, a torque loop and one SYNC of delay.
    """
    require_speed(CIA402_LOOP)
    from actuator_analysis.analyze import analyze_run, load_run
    from actuator_cia402.offline import DRIVE_SCENARIO, window_errors
    from actuator_cia402.offline import run as offline_drive
    from actuator_sim.loop import ClosedLoop
    from actuator_sim.params_yaml import all_scenarios

    duration = 5.0
    procs = _closed_loop(ros_process, tmp_path, {'stop_after_s': duration})
    code = procs['driver'].wait(60 + 5 * duration)
    log = procs['driver'].output
    late = _late_commands(log)
    if code != 0 and late is not None and late > LATE_COMMANDS_MAX:
        # The commands came too late and the driver ended control: its safe end must hold
        # whatever the cause; the tracking is excused only by the host's stalls.
        assert 'control ended:' in procs['driver'].output, procs['driver'].describe()
        skip_or_fail(
            host_window,
            f'{late:.1%} of the commands came too late and were refused; the driver ended '
            'control safely: '
            + re.search(r'control ended: [^\n]*', procs['driver'].output).group(0),
            samples=late * duration * 1000,
        )
    assert code == 0, procs['driver'].describe()
    for key in ('eso', 'controller', 'recorder'):
        assert procs[key].stop() == 0, procs[key].describe()
    # What must hold whatever the machine's load: the driver's own log shows the loop closed on the
    # SYNC grid, the controller never latched, currents stayed within the limit.
    samples = np.load(tmp_path / 'samples.npz')  # the driver's log, as the plant's
    stamps = samples['stamp_ns']
    assert stamps.size > 0 and np.all(np.diff(stamps) % 1_000_000 == 0)
    assert np.all(np.diff(stamps) > 0)
    assert 'safe stop latched' not in procs['controller'].output
    run = load_run(tmp_path / 'bag', quiet=True)  # the recorder (normal scheduling) may lose some
    assert np.all(np.isfinite(run.current)) and np.max(np.abs(run.current)) <= 20.0 + 1e-9
    answered = samples['held_command_stamp_ns'] > 0
    kept, answered_share = stamps.size / (duration * 1000), answered.mean()
    if kept <= 0.8 or answered_share <= 0.8:
        # Five Python processes at 1 kHz on 2 cores (issue 23): on an idle machine here the
        # driver's loop kept 25-92 % of its SYNC cycles (one run: 805 of 5000 skipped by its own
        # late wake-ups under SCHED_FIFO, 548 without a TPDO in time) and 2-12 % of the commands
        # came too late.
        lost = re.search(
            r'cycles skipped by host stalls \d+ \(the longest stall \d+\), '
            r'cycles without feedback \d+',
            log,
        )
        assert lost, procs['driver'].describe()  # the driver says where its cycles went
        skip_or_fail(
            host_window,
            f"the driver's log holds {kept:.0%} of the cycles ({lost.group(0)}), "
            f'{answered_share:.0%} of them with a command applied, {late or 0.0:.1%} of the '
            'commands refused as late; safety held (no latch, currents within 20 A, samples on '
            'the SYNC grid)',
            samples=duration * 1000 * (1.0 - kept * answered_share),
        )
    # the command applied over [t_k-1, t_k) answers a sample a few SYNCs older
    # (one SYNC of bus delay)
    lag_ms = (stamps[answered] - samples['held_command_stamp_ns'][answered]) / 1e6
    assert np.median(lag_ms) <= 3.0, np.median(lag_ms)
    delayed = float(np.mean(lag_ms > 1.5))  # applied a SYNC or more later than the design's one
    if delayed > DELAYED_COMMANDS_MAX:
        skip_or_fail(
            host_window,
            f'{delayed:.0%} of the commands applied a SYNC or more later than designed (the '
            'drive tuning is for one SYNC of delay); safety held (no latch, currents within '
            '20 A, samples on the SYNC grid)',
            samples=delayed * answered.sum(),
        )
    controlled = run.status == 0  # the rest: the stale stop after the run ended
    if controlled.sum() <= 0.5 * duration * 1000:
        # The recorder runs at normal scheduling beside four SCHED_FIFO processes on 2 cores: it
        # kept 840-2061 of the 5000 controlled states on runs here; the driver's log passed above.
        skip_or_fail(
            host_window,
            f'the recorder kept {controlled.sum()} controlled states of {duration * 1000:g}, '
            "too few to judge tracking (the driver's own log passed)",
            samples=duration * 1000 - controlled.sum(),
        )
    grid_ms = run.t[controlled] * 1e3
    assert np.allclose(
        grid_ms, np.round(grid_ms), atol=1e-6
    )  # measurement stamps on the 1 ms SYNC grid
    scenario = all_scenarios()[DRIVE_SCENARIO]  # what the loop through the drive runs
    scenario.duration_s = duration
    offline = ClosedLoop(scenario).run()
    window, offline_window = (
        controlled & (run.t >= 1.0) & (run.t < duration),
        offline['t_s'] >= 1.0,
    )
    max_run, max_offline = (
        np.max(np.abs(run.error[window])),
        np.max(np.abs(offline['error_rad'][offline_window])),
    )
    rms_run = np.sqrt(np.mean(run.error[window] ** 2))
    rms_offline = np.sqrt(np.mean(offline['error_rad'][offline_window] ** 2))

    max_model, rms_model = window_errors(offline_drive(duration_s=duration))
    longest_gap_ms = float(np.max(np.diff(stamps))) / 1e6
    print(
        f'end to end, t in [1, {duration:g}) s: max |e| {max_run:.2e} rad (offline core '
        f'{max_offline:.2e}, '
        f'offline with the drive model {max_model:.2e}), RMS {rms_run:.2e} rad (offline '
        f'{rms_offline:.2e}, '
        f'drive model {rms_model:.2e}); longest gap between samples {longest_gap_ms:.1f} ms'
    )
    assert max_run < 0.5  # the following-error limit: no latch
    stall_ms = limits.MEASUREMENT_TIMEOUT_S * 1e3
    if not fifo_granted():
        pytest.skip(
            'this machine refuses SCHED_FIFO: tracking through the drive is claimed only under it'
        )
    for key in ('driver', 'drive'):
        assert 'running under SCHED_FIFO' in procs[key].output, procs[key].describe()
    if longest_gap_ms >= stall_ms:
        # The controller's measurement timeout safe-stops and costs a transient (a run with one
        # 8 ms gap reached 5.7e-2 rad): excused only by a stall of the host that long.
        skip_or_fail(
            host_window,
            f'a gap of {longest_gap_ms:.0f} ms between samples (>= the {stall_ms:.0f} ms '
            f'measurement timeout): max |e| {max_run:.2e} rad',
            stall_ms=stall_ms,
        )
    # Measured under SCHED_FIFO on a 2-core VM (docs/cia402.md#tuned-for-the-drives-delay;
    # 2026-12-05, the drive's tuning drive_pp_nftsmc_eso): max |e| 2.26e-3 to 2.28e-3 rad, RMS
    # 7.52e-4 to 7.62e-4 in three runs; the offline core with the drive model (quantisation, torque
    # loop, one SYNC of command delay) 1.86e-3 and 7.71e-4. Bounds: 3x the measured figures. (With
    # Table 4's gains, 2026-12-02: max |e| 8.1e-3 and 9.3e-3, RMS 4.8e-4 and 5.6e-4.)
    assert analyze_run(run).metrics.bounds_kept
    assert rms_run < 3.0 * END_TO_END_RMS_RAD, rms_run
    assert max_run < 3.0 * END_TO_END_MAX_RAD, max_run


# A closed loop through the drive at 1 kHz: its timing is the machine's (one rerun, as for
# every realtime-marked test; see conftest).
@pytest.mark.realtime
def test_a_second_publisher_on_current_command_keeps_the_drive_braked(
    harness, ros_process, sim_drive
):
    # Old driver: no one-publisher guard and no stamp check; a second publisher at 20 A won
    # every SYNC. The joint node's guard now holds the drive at 0 A with the brake.
    from actuator_msgs.msg import CurrentCommand
    from actuator_ros.qos import control_qos

    drive, address = sim_drive()
    driver = ros_process(*DRIVER, driver_args(address, autostart=True))
    qos = control_qos('realtime')
    rogue = harness.node.create_publisher(CurrentCommand, 'current_command', qos)
    other = harness.node.create_publisher(CurrentCommand, 'current_command', qos)
    harness.wait_for(lambda: len(harness.joint) > 100, what='joint_states')
    wait_for_output(driver, r'2 publishers on current_command \(.*\): refusing every command', 20)
    for _ in range(300):  # 20 A answering each newest sample, from both publishers
        stamp = harness.joint[-1].header.stamp
        for pub in (rogue, other):
            msg = CurrentCommand(current_a=20.0)
            msg.header.stamp = stamp
            pub.publish(msg)
        harness.spin(0.002)
    assert 'operation enabled with' not in drive.stdout  # never enabled: braked throughout
    assert all(m.effort[0] == 0.0 for m in harness.joint[-100:])
    assert driver.stop() == 0 and 'Traceback' not in driver.output


#: The ends of control a 2-core host causes when it cannot run eight 1 kHz processes (the
#: drive process silent for 50 ms, then its consumer without SYNC): safe, with their reason.
HOST_ENDS = ('no TPDO from the drive in', "no SYNC from the bus's producer in")
#: The stall that ends control for one of HOST_ENDS: the driver's feedback timeout [ms].
SYNC_WATCHDOG_MS = 1e3 * DriverParameters.__dataclass_fields__['feedback_timeout_s'].default
#: CPUs two loops through the drive (eight 1 kHz processes) need to be judged on their timing.
CPUS_FOR_TWO_LOOPS = 4


@pytest.mark.realtime
def test_two_joints_on_one_bus_close_two_loops_under_namespaces(isolated):
    """The runner with two CiA 402 joints: one drive process with node ids 1 and 2.

    Hard for every run: drive 1's driver produces the SYNC and drive 2's consumes it, each
    checks the bus load of both, both joints sample, each loop's topics are in its namespace
    only (the bag); a run that ended early ended for a reason the host gives (a silent drive
    process, then a consumer without SYNC), safely (0 A, brake). Eight 1 kHz processes do not
    fit two cores: a consumer's ESO and controller below the drivers' priority got 60 of 3000
    measurements on one run here: the share of samples each driver applied its own controller's
    command over is judged (80 %) only on a host that ran both loops to their end.
    """
    require_speed(CIA402_LOOP)
    from rosbags.highlevel import AnyReader

    from actuator_bringup.run_description import JOINT_TOPICS
    from actuator_bringup.runner import run_closed_loop
    from actuator_bringup.supervisor import process_log

    result = run_closed_loop(
        'case2_pp_nftsmc_eso',
        'realtime',
        3.0,
        record=True,
        bag_root=isolated / 'bags',
        results_root=isolated / 'runs',
        quiet=True,
        thread_priority=CLOSED_LOOP_PRIORITY,
        joint='cia402_sim',
        joints=2,
    )
    logs = {k: process_log(result.run_dir, k) for k in result.exit_codes if k != 'bringup'}
    assert '(producer), bus load 73.5 % of 1000 kbit/s' in logs['driver1']
    assert '(consumer), bus load 73.5 % of 1000 kbit/s' in logs['driver2']
    assert all('for 2 joints' in logs[f'driver{i}'] for i in (1, 2))
    with AnyReader([result.bag]) as reader:
        topics = {conn.topic for conn in reader.connections}
    answered = {}
    ended = {k: code for k, code in result.exit_codes.items() if code != 0}
    for i in (1, 2):  # each loop in its own namespace, whatever the host did
        # (unless the other joint ended the run before this one started sampling)
        assert 'sampling started' in logs[f'driver{i}'] or ended, logs[f'driver{i}'][-2000:]
        assert f'[joint{i}.actuator_controller]: timing updates=' in logs[f'controller{i}']
        # the recorder (normal scheduling beside seven SCHED_FIFO processes) may miss a whole
        # topic on a starved host: each namespace is there, every topic is judged below
        assert any(t.startswith(f'/joint{i}/') for t in topics) or ended, topics
        samples = np.load(result.run_dir / f'plant_samples_joint{i}.npz')
        # the share of its samples over which the driver applied a command answering one of
        # its own samples (a command of the other joint's controller would answer none)
        answered[i] = float(np.isin(samples['held_command_stamp_ns'], samples['stamp_ns']).mean())
    assert topics <= {'/diagnostics'} | {f'/joint{i}/{t}' for i in (1, 2) for t in JOINT_TOPICS}
    assert set(ended) <= {'driver1', 'driver2'}, result.exit_codes
    for key in ended:  # a safe end, with the host's reason
        assert any(f'control ended: {why}' in logs[key] for why in HOST_ENDS), logs[key]
        assert '0 A, brake engaged' in logs[key]
    if len(os.sched_getaffinity(0)) < CPUS_FOR_TWO_LOOPS:
        # Eight 1 kHz processes on fewer CPUs than this do not keep their loops (measured on 2
        # cores: 1-8 % of joint 2's samples commanded): a property of the machine known before
        # the run, so the commanded share is judged on a machine with the CPUs only.
        pytest.skip(
            f'{len(os.sched_getaffinity(0))} CPUs: two loops through the drive are judged on '
            f'{CPUS_FOR_TWO_LOOPS} or more (ended {ended or "none"}, samples commanded by '
            f'their own controller {answered}; safety and namespaces judged above)'
        )
    assert not ended and min(answered.values()) >= 0.8, (ended, answered)
    assert topics == {'/diagnostics'} | {f'/joint{i}/{t}' for i in (1, 2) for t in JOINT_TOPICS}


@pytest.mark.realtime
def test_a_composed_cia402_loop_runs_driver_eso_and_controller_in_one_process(
    isolated, host_window
):
    """--composed with the CiA 402 joint: driver, ESO and controller on one executor.

    The simulated drive stays a process of its own (hardware). Hard: the three nodes ran in the
    container to the run's end, on the SYNC grid, without a latch. Tracking is the end-to-end
    test's; here the share of samples commanded is judged only on a host that kept the loop.
    """
    require_speed(CIA402_LOOP)
    from actuator_bringup.runner import run_closed_loop
    from actuator_bringup.supervisor import process_log

    result = run_closed_loop(
        'drive_pp_nftsmc_eso',
        'realtime',
        3.0,
        record=False,
        results_root=isolated / 'runs',
        quiet=True,
        thread_priority=CLOSED_LOOP_PRIORITY,
        joint='cia402_sim',
        composed=True,
    )
    log = process_log(result.run_dir, 'loop')
    assert result.exit_codes['drive'] == 0, result.exit_codes
    if result.exit_codes['loop'] != 0:  # only a safe end, with the reason a host gives
        ended = re.search(r'control ended: [^\n]*', log)
        assert ended and any(why in ended.group(0) for why in HOST_ENDS), log[-2000:]
        assert '0 A, brake engaged' in log
        skip_or_fail(
            host_window,
            f'the run ended early, safely: {ended.group(0)}',
            stall_ms=SYNC_WATCHDOG_MS,
        )
    for node in ('actuator_cia402_driver', 'actuator_eso', 'actuator_controller'):
        assert f'[{node}]: active' in log, log[-2000:]
    assert 'stopped at sample 3000' in log and 'safe stop latched' not in log
    samples = np.load(result.run_dir / 'plant_samples.npz')
    stamps = samples['stamp_ns']
    assert stamps.size > 0 and np.all(np.diff(stamps) % 1_000_000 == 0)
    answered = float(np.isin(samples['held_command_stamp_ns'], stamps).mean())
    if answered < 0.8:
        pytest.skip(
            f'the host kept {answered:.0%} of the samples commanded (no latch, on the grid)'
        )
