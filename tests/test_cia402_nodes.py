# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""CiA 402 driver node as a ROS process (ROS-PROCESS TESTS: each starts installed executables).

The driver is the joint node holding a Cia402Joint; the simulated drive (``cia402_sim_drive``)
runs in a process of its own, as hardware would. Parameter refusals, the lifecycle driven
through its services (what ``ros2 lifecycle set`` calls), a drive fault in mid-run and its
acknowledgement by a person. The real-time runs (a silent drive against the real controller,
kill -9 of the driver in closed loop, a second publisher on current_command, the end-to-end
closed loop) are in tests/test_cia402_realtime.py; the shared pieces in tests/cia402_helpers.py.
"""

import subprocess

import numpy as np
import pytest

from cia402_helpers import (  # noqa: F401 - fixtures by name
    DRIVER,
    NODE,
    driver_args,
    harness_fixture,
    sim_drive_fixture,
    wait_for_output,
)
from ros_helpers import executable_path

#: SCHED_FIFO priorities of the simulated drive and the driver where a test runs them at the
#: real-time loop's (run_description: the joint one above the loop's 50, the drive one above that).
DRIVER_PRIORITY, DRIVE_PRIORITY = 51, 52


@pytest.mark.parametrize(
    'params, word',
    [
        (['-p', 'node_id:=0'], 'node_id'),
        (['-p', 'node_id:=abc'], 'node_id'),
        (['-p', 'bitrate:=125000'], '320.0 % of 125 kbit/s'),
        (['-p', 'interface:=pcan'], 'interface'),
        (['-p', 'sample_time_s:=0.0'], 'sample_time_s'),
        (['-p', 'interface:=socketcan'], 'simulated_drive'),
        (['-p', 'current_limit_a:=-1.0'], 'current_limit_a'),
        (['-p', 'use_sim_time:=true'], 'use_sim_time'),
        (['-p', 'heartbeat_timeout_s:=0.01'], 'twice'),
    ],
)
def test_every_parameter_refusal_is_one_line_and_exit_2(ros_env, params, word):
    """Bad values and combinations: exit 2, one line on stderr naming the parameter."""
    proc = subprocess.run(
        [executable_path(*DRIVER), *driver_args(), *params],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert len(lines) == 1 and word in lines[0] and lines[0].startswith('cia402_driver: '), (
        proc.stderr
    )
    assert 'Traceback' not in proc.stderr + proc.stdout


@pytest.mark.parametrize(
    'params, words',
    [
        (['-p', 'simulated_drive:=false', '-p', 'interface:=socketcan'], 'eds_file must name'),
        (['-p', 'eds_file:=/nonexistent/x.eds'], "parameter 'eds_file' = '/nonexistent/x.eds'"),
    ],
)
def test_configure_refuses_a_real_bus_without_its_eds_before_the_bus(ros_env, params, words):
    # Old driver: eds_file defaulted to the simulated drive's EDS, on a real bus too.
    proc = subprocess.run(
        [executable_path(*DRIVER), *driver_args(), *params, '-p', 'autostart:=true'],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert f'configure refused: {words}' in proc.stderr and 'Traceback' not in proc.stderr
    assert 'node 1 on' not in proc.stderr  # refused before the bus was opened


def test_500_kbit_at_1_khz_starts_with_the_bus_load_warning(ros_process):
    """80 % of 500 kbit/s is accepted with a warning that names the figure."""
    driver = ros_process(*DRIVER, driver_args(bitrate=500000))
    driver.wait_for_output(r'bus load 80\.0 % of 500 kbit/s .* is above 60 %', timeout=30)
    assert driver.stop() == 0


def test_lifecycle_configure_activate_deactivate_through_the_services(
    harness, ros_process, sim_drive
):
    """No joint_states until active; stamps on the 1 ms grid, effort; none after deactivate.

    The drive and the driver at the real-time loop's priorities (SCHED_FIFO where granted): a
    drive process that a loaded host stalls for 50 ms is a silent drive, and the driver rightly
    ends control on it.
    """
    from actuator_core.timing import stamp_to_ns

    drive, address = sim_drive('--thread-priority', str(DRIVE_PRIORITY))
    driver = ros_process(*DRIVER, driver_args(address, thread_priority=DRIVER_PRIORITY))
    assert harness.state() == 'unconfigured'
    from rcl_interfaces.srv import DescribeParameters

    describe = harness.node.create_client(DescribeParameters, f'/{NODE}/describe_parameters')
    answer = harness.call(
        describe, DescribeParameters.Request(names=['heartbeat_timeout_s', 'node_id'])
    )
    heartbeat, node_id = answer.descriptors
    assert '0x1016' in heartbeat.description and node_id.integer_range[0].to_value == 127
    assert harness.transition('configure') and harness.state() == 'inactive'
    harness.spin(0.5)
    assert harness.joint == []  # configured: no joint_states
    assert harness.transition('activate') and harness.state() == 'active'
    harness.wait_for(lambda: len(harness.joint) > 300, what='joint_states while active')
    msg = harness.joint[-1]
    assert list(msg.name) == ['joint'] and len(msg.position) == 1 and len(msg.effort) == 1
    assert msg.effort[0] == 0.0  # no command yet: the brake holds, no torque
    stamps = np.array([stamp_to_ns(m.header.stamp) for m in harness.joint])
    period = np.diff(stamps)
    assert np.all(period % 1_000_000 == 0) and np.all(period > 0)  # on the 1 ms grid
    assert 'brake released' not in drive.stdout  # no command: never enabled
    assert harness.transition('deactivate') and harness.state() == 'inactive'
    harness.spin(0.3)
    count = len(harness.joint)
    harness.spin(0.5)
    assert len(harness.joint) == count  # deactivated: no more samples
    assert harness.transition('cleanup') and harness.state() == 'unconfigured'
    assert harness.transition('configure') and harness.transition('activate')  # and again
    harness.wait_for(
        lambda: len(harness.joint) > count + 100, what='joint_states after re-activation'
    )
    assert driver.stop() == 0 and 'Traceback' not in driver.output, driver.output[-4000:]
    assert drive.running  # the drive outlives its master, as hardware does


def test_drive_fault_ends_control_and_only_a_person_resets_it(harness, ros_process, sim_drive):
    """Over-current mid-run: error processing, and no activate until acknowledge_fault.

    Configure reports the fault; activate is refused until a person calls the service.
    """
    from std_srvs.srv import Trigger

    drive, address = sim_drive('--fault-kind', 'over_current', '--fault-at', '1.0')
    driver = ros_process(*DRIVER, driver_args(address, autostart=True))
    wait_for_output(driver, r'0x2310 continuous over-current', timeout=30)
    harness.wait_for(lambda: harness.state() == 'unconfigured', what='error processing')
    harness.joint.clear()
    harness.spin(0.5)
    assert harness.joint == []  # measurements stopped
    assert harness.transition('configure')
    wait_for_output(driver, r'drive is in fault 0x2310 .* no automatic reset', timeout=10)
    assert not harness.transition('activate')  # refused: no automatic fault reset
    wait_for_output(driver, r'activate refused: .*acknowledge', timeout=10)
    acknowledge = harness.node.create_client(Trigger, f'/{NODE}/acknowledge_fault')
    answer = harness.call(acknowledge, Trigger.Request())
    assert answer.success and 'acknowledged' in answer.message
    assert harness.transition('activate')
    harness.wait_for(lambda: len(harness.joint) > 50, what='joint_states after acknowledging')
    assert driver.stop() == 0 and 'Traceback' not in driver.output, driver.output[-4000:]
