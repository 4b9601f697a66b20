# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The running loop attacked as an adversarial user would.

The loop keeps tracking, or stops safely with the reason logged and resumes as the policy says
(README "Safety").

Each test runs plant, ESO, controller and recorder in real time (SCHED_FIFO where the kernel
allows) on an isolated domain, attacks the loop from this process at about 3 s, and judges the
recorded run: no latched stop, the reason in the nodes' logs, and controlled samples tracking
again (|e| small) at the end.
"""

import math
import time
from pathlib import Path

import pytest

from actuator_core.timing import stamp_to_ns
from actuator_ros.conversions import ns_to_stamp
from actuator_tools.graph import closed_loop, ros_arguments
from actuator_tools.supervisor import RosProcess, process_log

pytestmark = [pytest.mark.realtime, pytest.mark.slow]

SCENARIO = 'case2_pp_nftsmc_eso'
#: |e| of the controlled samples in the last second that counts as tracking again [rad]. The
#: paper's run stays below 1e-3 rad in steady state; after a restart the envelope's transient
#: (rho0 = 0.25 rad) is still decaying, hence the margin.
TRACKING_RAD = 0.05


class Loop:
    """The closed loop as processes, from the one description (graph.closed_loop).

    With restarts.
    """

    def __init__(self, env: dict, tmp: Path):
        from ament_index_python.packages import get_package_share_directory

        self.env, self.tmp = env, tmp
        self.params = (
            Path(get_package_share_directory('actuator_bringup')) / 'config' / f'{SCENARIO}.yaml'
        )
        self.bag = tmp / 'bag'
        self.specs = {
            s.key: s
            for s in closed_loop('realtime', 0.0, record=True, bag=self.bag, thread_priority=50)
        }
        self.procs: dict[str, RosProcess] = {}
        self.starts: dict[str, int] = {}
        for key in self.specs:
            self.start(key)

    def start(self, key: str) -> RosProcess:
        spec = self.specs[key]
        n = self.starts[key] = self.starts.get(key, 0) + 1
        proc = RosProcess.installed(
            spec.package,
            spec.executable,
            ros_arguments(spec, self.params),
            env=self.env,
            log_dir=self.tmp / 'logs',
            name=f'{key}{n}',
        )
        self.procs[key] = proc
        return proc

    def restart(self, key: str, pause_s: float = 0.5) -> None:
        """SIGINT the process (as Ctrl-C or a crash handler would), wait, start a new one."""
        assert self.procs[key].stop() == 0
        time.sleep(pause_s)
        self.start(key)

    def log(self, key: str) -> str:
        """Everything every process of ``key`` (the first and any restarted one) wrote."""
        return ''.join(
            process_log(self.tmp / 'logs', f'{key}{n}') for n in range(1, self.starts[key] + 1)
        )

    def stop(self) -> dict:
        return {k: p.stop() for k, p in reversed(list(self.procs.items()))}


class Attacker:
    """An rclpy node in the test process: the rogue publisher and the listener."""

    def __init__(self, context):
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        from actuator_msgs.msg import ControllerState, CurrentCommand, PlantTruth, StateEstimate
        from actuator_ros.qos import control_qos
        from sensor_msgs.msg import JointState

        self.types = {
            'joint_states': JointState,
            'eso/estimate': StateEstimate,
            'current_command': CurrentCommand,
        }
        self.node = Node('attacker', context=context)
        self.qos = control_qos('realtime')
        self.states: list = []
        self.truth: list = []
        self.node.create_subscription(
            ControllerState, 'controller/state', self.states.append, self.qos
        )
        self.node.create_subscription(PlantTruth, 'plant/truth', self.truth.append, self.qos)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)

    def wait_until_controlling(self, timeout: float = 60.0) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.spin(0.2)
            if sum(s.status == 0 for s in self.states[-200:]) > 150:
                return
        raise AssertionError('the loop never reached closed-loop control')

    def newest_stamp_ns(self) -> int:
        return stamp_to_ns(self.truth[-1].header.stamp)

    def publisher(self, topic: str):
        return self.node.create_publisher(self.types[topic], topic, self.qos)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


def tracking_again(attacker: Attacker, seconds: float = 1.0) -> float:
    """Max |e| of the controlled samples in the last ``seconds`` (inf when none was controlled)."""
    recent = attacker.states[-int(seconds * 1000) :]
    errors = [abs(s.error_rad) for s in recent if s.status == 0 and math.isfinite(s.error_rad)]
    return max(errors) if len(errors) > 0.5 * len(recent) else math.inf


@pytest.fixture
def loop(ros_env, rclpy_context, tmp_path):
    running = Loop(ros_env, tmp_path)
    attacker = Attacker(rclpy_context)
    try:
        attacker.wait_until_controlling()
        yield running, attacker
    finally:
        attacker.close()
        codes = running.stop()
        assert all(c == 0 for c in codes.values()), codes
        assert not any('Traceback' in running.log(key) for key in running.specs)


def _assert_recovered(running: Loop, attacker: Attacker) -> None:
    attacker.spin(3.0)
    assert 'safe stop latched' not in running.log('controller')
    assert tracking_again(attacker) < TRACKING_RAD, tracking_again(attacker)


def test_future_and_past_stamps_on_every_input_are_refused_and_tracking_goes_on(loop):
    running, attacker = loop
    now = attacker.newest_stamp_ns()
    js, est, cmd = (
        attacker.publisher(t) for t in ('joint_states', 'eso/estimate', 'current_command')
    )
    future = ns_to_stamp(now + 1000 * 10**9)
    m = attacker.types['joint_states'](name=['joint'], position=[0.0])
    m.header.stamp = future
    js.publish(m)  # one measurement 1000 s ahead
    for k in range(100):  # 100 estimates ahead
        e = attacker.types['eso/estimate'](velocity_rad_s=0.0, input_current_gain=0.03)
        e.header.stamp = ns_to_stamp(now + (1000 + k) * 10**9)
        est.publish(e)
    c = attacker.types['current_command'](current_a=5.0)
    c.header.stamp = future
    cmd.publish(c)
    for pub in (js, est, cmd):
        attacker.node.destroy_publisher(pub)
    _assert_recovered(running, attacker)
    assert 'refused: beyond the sample clock' in running.log('controller')
    assert 'refused' in running.log('eso') and 'refused' in running.log('plant')


def test_nan_and_absurd_values_in_each_field_are_refused(loop):
    running, attacker = loop
    est = attacker.publisher('eso/estimate')
    attacker.spin(0.3)
    now = attacker.newest_stamp_ns()
    for field, value in (
        ('input_current_a', math.nan),
        ('velocity_rad_s', 1.0e9),
        ('input_current_gain', 1.0e12),
        ('disturbance_rad_s2', math.inf),
    ):
        e = attacker.types['eso/estimate'](input_current_gain=0.03)
        setattr(e, field, value)
        e.header.stamp = ns_to_stamp(now + 2 * 10**6)
        est.publish(e)
    attacker.node.destroy_publisher(est)
    _assert_recovered(running, attacker)
    log = running.log('controller')
    for field in ('input_current_a', 'velocity_rad_s', 'input_current_gain', 'disturbance_rad_s2'):
        assert f'{field} = ' in log


@pytest.mark.parametrize('topic, guard', [('current_command', 'plant'), ('joint_states', 'eso')])
def test_a_second_publisher_stops_control_safely_until_it_leaves(loop, topic, guard):
    running, attacker = loop
    rogue = attacker.publisher(topic)
    end = time.monotonic() + 0.6
    while time.monotonic() < end:  # a rogue script drives the topic for 0.6 s
        m = attacker.types[topic]()
        if topic == 'current_command':
            m.current_a = 5.0
        else:
            m.name, m.position = ['joint'], [1.0]
        m.header.stamp = ns_to_stamp(attacker.newest_stamp_ns())
        rogue.publish(m)
        attacker.spin(0.002)
    assert any(s.status == 7 for s in attacker.states[-1000:]), (
        'the controller never reported the conflict'
    )
    attacker.node.destroy_publisher(rogue)
    _assert_recovered(running, attacker)
    assert f'2 publishers on {topic}' in running.log(guard)
    assert f'2 publishers on {topic}' in running.log('controller')


@pytest.mark.parametrize(
    'key, what',
    [
        ('plant', 'time base jumped'),
        # The controller resyncs on the restarted observer's first estimate, or first on the
        # measurement gap the restart caused (seen once in a fresh-clone run): either says this.
        ('eso', "then the reference restarts from the joint's angle"),
        ('controller', ''),
    ],
)
def test_a_restarted_node_resumes_control(loop, key, what):
    running, attacker = loop
    running.restart(key)
    end = time.monotonic() + 60.0
    while (
        time.monotonic() < end
        and running.procs[key].running
        and 'active' not in running.procs[key].output
    ):
        attacker.spin(0.2)
    attacker.spin(2.0)
    _assert_recovered(running, attacker)
    if what:
        assert what in running.log('controller')
    braked = [t.brake_engaged for t in attacker.truth]
    assert any(braked), 'the joint was never braked while control was down'
