# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Helpers shared by the CiA 402 driver node tests (test_cia402_nodes, test_cia402_realtime).

The driver's executable and node name, its command line, a wait on a process's output that
dumps its threads on a timeout, and two fixtures, which a test module imports by name:

    sim_drive   factory: sim_drive(*args) -> (process, hub address) of a started
                ``cia402_sim_drive`` (a ros_process, stopped when the test ends)
    harness     the driver's test node (Harness) on the test's rclpy context, closed at its end
"""

import os
import re
import signal
import time

import pytest

from ros_helpers import TestNode

DRIVER = ('actuator_cia402', 'cia402_driver')
NODE = 'actuator_cia402_driver'


def wait_for_output(proc, pattern, timeout):
    """proc.wait_for_output.

    On a timeout the process first dumps its threads' stacks (SIGUSR1) into the report.
    """
    try:
        return proc.wait_for_output(pattern, timeout=timeout)
    except TimeoutError:
        if proc.running:
            os.kill(proc.pid, signal.SIGUSR1)
            time.sleep(1.0)
        raise AssertionError(
            f'{proc.name} did not print {pattern!r} within {timeout} s\n{proc.describe(tail=120)}'
        ) from None


def driver_args(address='127.0.0.1:1', **params) -> list:
    """Command line of the driver: the simulated drive's hub at ``address``, plus ``params``."""
    from actuator_cia402.launch_spec import driver_arguments

    base = {'simulated_drive': True, 'interface': 'hub', 'channel': address}
    base.update(params)
    return driver_arguments(base)


@pytest.fixture(name='sim_drive')
def sim_drive_fixture(ros_process):
    """Start ``cia402_sim_drive`` with extra arguments; return (process, hub address)."""

    def start(*args):
        drive = ros_process('actuator_cia402', 'cia402_sim_drive', ['--port', '0', *args])
        drive.wait_for_output(r'^drive 1 ready$', timeout=30)
        return drive, re.search(r'bus hub on (\S+)', drive.stdout).group(1)

    return start


class Harness(TestNode):
    """The driver's test node: joint_states, diagnostics, commands; its lifecycle services."""

    def __init__(self, context):
        """Subscriptions on the test's rclpy context."""
        from diagnostic_msgs.msg import DiagnosticArray
        from sensor_msgs.msg import JointState

        from actuator_msgs.msg import CurrentCommand
        from actuator_ros.qos import control_qos

        super().__init__(context, 'cia402_harness')
        qos = control_qos('realtime')
        self.joint, self.diag, self.command = [], [], []
        self.node.create_subscription(JointState, 'joint_states', self.joint.append, qos)
        self.node.create_subscription(DiagnosticArray, 'diagnostics', self.diag.append, 10)
        self.node.create_subscription(CurrentCommand, 'current_command', self.command.append, qos)

    def transition(self, label):
        """Request a lifecycle transition of the driver by label; True on success."""
        return super().transition(NODE, label)

    def state(self):
        """Return the driver's lifecycle state label (``ros2 lifecycle get``)."""
        return self.lifecycle_state(NODE)

    def diag_values(self):
        """Key/values of the newest diagnostics status."""
        return {kv.key: kv.value for kv in self.diag[-1].status[0].values} if self.diag else {}


@pytest.fixture(name='harness')
def harness_fixture(rclpy_context):
    """Return a Harness for the test, destroyed at its end."""
    h = Harness(rclpy_context)
    yield h
    h.close()
