# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``cia402_torque_test`` as the first-power-on checklist uses it (issue 44 item 6).

The tool in its own process against ``cia402_sim_drive`` in another, as on the bench: the
limits it writes, the refusal of a current above them, the automatic sign check, and the stop
on Ctrl-C, each judged by what the DRIVE shows over SDO (a service tool on the hub). Each
comment says what the tool before issue 44 did, and so why the test fails on it (checked with
its torque_test.py, joint.py and master.py of 6a9c8a1). Steps 4 and 8 of
docs/how-to/real-cia402-joint.md are taken from the page as written: the tool's command run on
the simulated drive (the bus changed, nothing else) printing the lines the page quotes, and the
driver's parameters a real drive the driver takes.
"""

from __future__ import annotations

import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import canopen
import pytest
import yaml

from actuator_bringup.supervisor import RosProcess
from actuator_cia402 import profile as p
from actuator_cia402.hub import HubBus
from actuator_cia402.sim_drive_main import default_eds

pytestmark = pytest.mark.ros  # processes: the simulated drive and the tool
PERIOD_S = 0.002
TOOL = [sys.executable, '-m', 'actuator_cia402.torque_test']


@pytest.fixture
def bench(tmp_path):
    """Start a simulated drive (free joint unless told) and a service tool on its hub."""
    started, networks = [], []

    def start(*drive_args):
        drive = RosProcess(
            [
                sys.executable,
                '-m',
                'actuator_cia402.sim_drive_main',
                '--sync-period',
                str(PERIOD_S),
                '--no-load',
                *drive_args,
            ],
            log_dir=tmp_path,
            name='sim_drive',
        )
        started.append(drive)
        drive.wait_for_output(r'^drive 1 ready$', timeout=30)
        address = re.search(r'bus hub on (\S+)', drive.stdout).group(1)
        network = canopen.Network(HubBus(address))
        network.NOTIFIER_CYCLE = 0.1
        network.connect()
        networks.append(network)
        node = canopen.RemoteNode(1, default_eds())
        network.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 1.0
        return address, node

    yield start
    for network in networks:
        network.disconnect()
    for proc in started:
        proc.stop()


def tool(address, tmp_path, *args) -> RosProcess:
    """Start the tool on the simulated drive's hub, as the checklist's step 4 runs it."""
    command = [*TOOL, '--interface', 'hub', '--channel', address, '--simulated']
    command += ['--sync-period', str(PERIOD_S), *args]
    return RosProcess(command, log_dir=tmp_path, name='torque_test')


def drive_state(node) -> tuple:
    """Return the drive's state, current actual [A] and brake, read over SDO."""
    time.sleep(0.05)  # one SDO channel, two clients: the tool's answers must be gone first
    state = p.decode_state(node.sdo[p.STATUSWORD].raw)
    current = node.sdo[p.CURRENT_ACTUAL].raw / 100.0  # rated 10 A = 1000 per mille
    brake = bool(node.sdo[p.DIGITAL_INPUTS].raw & (1 << 16))
    return state, current, brake


def test_a_current_above_the_limit_is_refused_in_one_line():
    # Before: there was no --current-limit; the tool configured the 20 A project limit and took
    # any --current.
    done = subprocess.run(
        [*TOOL, '--simulated', '--interface', 'hub', '--current', '0.8', '--current-limit', '0.5'],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        'cia402_torque_test: --current 0.8 A is above --current-limit 0.5 A (written to the '
        'drive as 0x6072/0x6073): refused'
    ]


def test_the_limits_reach_the_drive(bench, tmp_path):
    # Before: 0x6072/0x6073 got 20 A and 0x6080 19 099 rpm whatever the checklist asked (the
    # tool had no --current-limit or --velocity-limit, and refused these arguments).
    address, node = bench()
    limits = ('--current-limit', '0.5', '--velocity-limit', '2')
    run = tool(address, tmp_path, *limits, '--current', '0.3', '--duration', '60')
    try:
        run.wait_for_output(r'applying 0.3 A', timeout=30)
        assert node.sdo[p.MAX_CURRENT].raw == 50  # 0.5 A of the 10 A rated, per mille
        assert node.sdo[p.MAX_TORQUE].raw == 50
        assert node.sdo[p.MAX_MOTOR_SPEED].raw == 1910  # 2 rad/s x 100 in rpm, rounded up
    finally:
        run.stop()


def test_ctrl_c_leaves_the_drive_disabled_and_braked(bench, tmp_path):
    # Before: Ctrl-C skipped the tool's deactivate (a traceback): the drive kept 0.3 A until
    # its heartbeat consumer quick-stopped it 300 ms later and stayed in quick stop active.
    address, node = bench()
    run = tool(address, tmp_path, '--current', '0.3', '--duration', '60')
    try:
        run.wait_for_output(r'applying 0.3 A', timeout=30)
        assert drive_state(node)[:2] == (p.State.OPERATION_ENABLED, 0.3)
        run.popen.send_signal(signal.SIGINT)
        code = run.wait(10)
    finally:
        run.stop()
    assert drive_state(node) == (p.State.SWITCH_ON_DISABLED, 0.0, True)
    assert node.sdo[p.HEARTBEAT_CONSUMER][1].raw == 0  # cleared: the drive was seen disabled
    assert code == 130 and 'interrupted: stopping the drive' in run.stdout
    assert re.search(r"deactivated: drive 'switch on disabled' \(statusword 0x\w+\)", run.stdout)


@pytest.mark.parametrize(
    'encoder_sign, code, line',
    [
        (1, 0, 'sign check: +0.3 A moved the joint its way: the sign is right'),
        (-1, 3, 'cia402_torque_test: sign check failed: +0.3 A moved the joint -'),
    ],
)
def test_the_sign_check_passes_a_right_drive_and_stops_a_wrong_one(
    bench, tmp_path, encoder_sign, code, line
):
    # Before: the direction was left to the eye of whoever watched; an encoder counting
    # against the torque ran the whole --duration (exit 0).
    address, node = bench('--encoder-sign', str(encoder_sign))
    run = tool(
        address, tmp_path, '--current-limit', '0.5', '--velocity-limit', '1', '--current', '0.3'
    )
    assert run.wait(60) == code, run.describe()
    assert line in run.output, run.describe()
    assert re.search(r'samples \d+, missed TPDOs \d+, position .* rad, mean torque', run.stdout)
    assert drive_state(node) == (p.State.SWITCH_ON_DISABLED, 0.0, True)


# --- docs/how-to/real-cia402-joint.md, word for word -----------------------------------------
PAGE = Path(__file__).resolve().parents[1] / 'docs' / 'how-to' / 'real-cia402-joint.md'


def _step(number: int) -> str:
    """Return the text of the page's step ``number`` (its heading to the next)."""
    return re.search(rf'\n## {number}\. .*?(?=\n## |\Z)', PAGE.read_text(), flags=re.S)[0]


def _command(step: str) -> list[str]:
    """Return the step's first fenced command, continuation lines joined, as words."""
    body = re.search(r'```\n(.*?)```', step, flags=re.S)[1]
    return shlex.split(body.replace('\\\n', ' '))


def test_step_4_runs_as_written_on_the_simulated_drive_and_prints_what_it_says(bench, tmp_path):
    # The command of step 4 with the bus changed and nothing else: the simulated drive's hub
    # for can0, its EDS for the vendor's; the lines the page tells the user to check, as it
    # quotes them ('...' any text).
    step = _step(4)
    words = _command(step)
    assert words[:4] == ['ros2', 'run', 'actuator_cia402', 'cia402_torque_test'], words
    args = words[4:]
    args[args.index('--eds') + 1] = default_eds()
    address, node = bench()
    args[args.index('--channel') + 1] = address
    run = tool(address, tmp_path, *args)
    assert run.wait(60) == 0, run.describe()
    checks = step.split('In the output, check:')[1].split('Beyond')[0]
    quoted = [' '.join(q.split()) for q in re.findall(r'`([^`]+)`', checks)]  # lines unwrapped
    expected = [q for q in quoted if q.startswith(('sign check: ', 'samples ', 'control ended'))]
    expected += [q for q in quoted if q.startswith('deactivated: ')]
    assert len(expected) == 4, quoted
    number = r'[-+]?\d+(?:\.\d+)?'
    for line in expected:
        pattern = re.escape(line).replace(r'\.\.\.', '.*')
        if line.startswith('samples '):
            # N, M, A, B, T stand for numbers; N m (newton metre) is the unit
            pattern = re.sub(r'\b[NMABT]\b(?!\\ m\b)', lambda _: number, pattern)
        assert re.search(pattern, run.stdout), (line, run.stdout)
    assert drive_state(node) == (p.State.SWITCH_ON_DISABLED, 0.0, True)
    assert node.sdo[p.MAX_CURRENT].raw == 50  # --current-limit 0.5: 0.5 A of the 10 A rated


def test_step_8_parameters_are_a_real_drive_the_driver_takes():
    # Every '-p name:=value' of step 8 as the node reads it (the joint node's settings, the
    # driver's, the node's thread priority): each name known, and a real drive (socketcan)
    # with the settings step 1 asks for, none refused.
    from dataclasses import fields

    from actuator_cia402.config import DriverParameters, check_real_drive
    from actuator_cia402.driver_node import FROM_JOINT_SETTINGS
    from actuator_core.joint import JointSettings

    values = {}
    for word in _command(_step(8)):
        name, sep, text = word.partition(':=')
        if sep:
            values[name] = yaml.safe_load(text)  # as the ROS 2 command line types it
    assert values.pop('thread_priority') == 51  # the node's, above the loop's 50
    joint_names = {f.name for f in fields(JointSettings)}
    drive_names = {f.name for f in fields(DriverParameters)} - set(FROM_JOINT_SETTINGS)
    assert set(values) <= joint_names | drive_names, set(values) - joint_names - drive_names
    joint = JointSettings(**{k: v for k, v in values.items() if k in joint_names})
    drive = DriverParameters(
        **{k: v for k, v in values.items() if k in drive_names},
        current_limit_a=joint.current_limit_a,
    )
    check_real_drive(drive, (joint.position_min_rad, joint.position_max_rad))
    assert (drive.interface, drive.simulated_drive) == ('socketcan', False)
    assert (drive.brake_status_index, drive.brake_status_mask) == (0x60FD, 1 << 16)
    assert (joint.current_limit_a, drive.velocity_limit_rad_s) == (2.0, 2.0)
