# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""run_nodes runs every node through the one ProcessMember contract, in its stated order.

Each case is a process of its own (run_nodes owns rclpy.init and the signal handlers): a
probe node that writes down each call of the contract.
"""

import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.ros

#: A probe member: finished after a few spins; settles after three asks; what it was asked,
#: in order, on stdout; ``FAIL_RELEASE`` makes its release fail.
PROBE = textwrap.dedent(
    """
    import sys
    from rclpy.node import Node
    from actuator_ros.process_member import MemberError, ProcessMember
    from actuator_ros.runner import run_nodes

    class Probe(Node, ProcessMember):
        def __init__(self, settings):
            super().__init__('probe')
            self.asked_to_settle = 0
            self.create_timer(0.01, self.tick)
            self.ticks = 0

        def tick(self):
            self.ticks += 1
            self.finished = self.ticks >= 3

        def autostart(self):
            print('autostart', flush=True)
            return AUTOSTART

        def halt(self):
            print('halt', flush=True)

        def settled(self):
            self.asked_to_settle += 1
            return self.asked_to_settle >= 3

        def release(self):
            print(f'release after {self.asked_to_settle} asks to settle', flush=True)
            if FAIL_RELEASE:
                raise MemberError('the bag could not be closed')

    FACTORY = FACTORY_SOURCE
    sys.exit(run_nodes('probe', 'a probe', [FACTORY], 'probe', []))
    """
)


def _run(ros_env, factory: str, autostart: bool = True, fail_release: bool = False):
    settings = f'AUTOSTART, FAIL_RELEASE = {autostart}, {fail_release}\n'
    script = settings + PROBE.replace('FACTORY_SOURCE', factory)
    return subprocess.run(
        [sys.executable, '-c', script],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_a_member_is_started_halted_settled_and_released_in_that_order(ros_env):
    proc = _run(ros_env, 'Probe')
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [
        'autostart',
        'halt',
        'release after 3 asks to settle',
    ], proc.stdout


def test_a_failed_release_is_one_error_line_and_exit_1(ros_env):
    proc = _run(ros_env, 'Probe', fail_release=True)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    errors = [x for x in proc.stderr.splitlines() if x.startswith('probe: error:')]
    assert errors == ['probe: error: the bag could not be closed'], proc.stderr
    assert 'Traceback' not in proc.stderr


def test_a_refused_autostart_exits_2_and_still_releases(ros_env):
    proc = _run(ros_env, 'Probe', autostart=False)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert 'probe: autostart of probe: configure or activate failed' in proc.stderr
    assert proc.stdout.splitlines()[-1].startswith('release'), proc.stdout


def test_a_node_outside_the_contract_is_refused_by_name(ros_env):
    proc = _run(ros_env, "lambda settings: Node('stranger')")
    assert proc.returncode != 0
    assert 'Node is not a ProcessMember' in proc.stderr, proc.stderr
