# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Shared test tooling: isolated ROS domains, installed executables, managed processes.

Everything here expects the project environment (``source scripts/env.sh``; ``make test``
does it). The pytest fixtures built on it live in ``tests/conftest.py``.

Isolation: each test gets its own ``ROS_DOMAIN_ID``, reserved with ``domain_coordinator`` (the
pinned ROS 2 package launch_testing uses) so that parallel pytest processes never share one, and
discovery restricted to this host (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, no static peers, no
discovery server, no deprecated ``ROS_LOCALHOST_ONLY``).
"""

from __future__ import annotations

import os
import random
import threading
import time
from pathlib import Path
from typing import Iterable, Mapping, Optional, Union

import domain_coordinator

# The process supervisor is the product's own (actuator_bringup.supervisor), shared with the
# runner.
from actuator_bringup.supervisor import (
    RosProcess,
    executable_path,
    live_processes,
    stop_all_processes,
)

#: Variables that decide whom a ROS process can discover. ``isolated_ros_env`` sets or
#: removes every one of them.
ISOLATION_SET = ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_STATIC_PEERS')
ISOLATION_UNSET = ('ROS_LOCALHOST_ONLY', 'ROS_DISCOVERY_SERVER', 'ROS_SUPER_CLIENT')

WORKSPACE = Path(__file__).resolve().parent.parent


class _RandomStart:
    """domain_coordinator's selector, started at a random id.

    So parallel runs rarely collide on the first try.
    """

    def __init__(self, exclude: Iterable[int] = ()):
        self.value = random.randrange(100)
        self.exclude = set(exclude)

    def __call__(self) -> int:
        while True:
            self.value += 1
            candidate = self.value % 100 + 1
            if candidate not in self.exclude:
                return candidate


def reserve_domain(exclude: Iterable[int] = ()):
    """Return a ROS_DOMAIN_ID in 1..100 held for this process alone.

    domain_coordinator: a bound port per id.
    """
    return domain_coordinator.domain_id(selector=_RandomStart(exclude))


def isolated_ros_env(
    domain_id: int,
    base: Optional[Mapping[str, str]] = None,
    log_dir: Optional[Union[str, Path]] = None,
) -> dict:
    """Return an environment for a ROS subprocess.

    It sees only processes of ``domain_id`` on this host.
    """
    env = dict(os.environ if base is None else base)
    for name in ISOLATION_UNSET:
        env.pop(name, None)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['ROS_STATIC_PEERS'] = ''
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    # Output reaches the capture files at once, without colour codes.
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_LOGGING_BUFFERED_STREAM'] = '0'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    if log_dir is not None:
        env['ROS_LOG_DIR'] = str(log_dir)
    return env


def check_project_environment() -> Optional[str]:
    """None when scripts/env.sh is in effect, otherwise what is missing."""
    if not os.environ.get('ACTUATOR_WS'):
        return 'ACTUATOR_WS is not set'
    prefixes = os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
    install = str(WORKSPACE / 'install')
    if not any(p.startswith(install) for p in prefixes):
        return (
            f'AMENT_PREFIX_PATH has no package of {install} (not built, or '
            'install/setup.bash not sourced)'
        )
    return None


def env_without_workspace(env: Mapping[str, str], workspace: Union[str, Path] = WORKSPACE) -> dict:
    """``env`` minus everything the workspace overlay (install/, build/) added to it.

    Leaves the underlay (venv or /opt/ros/jazzy) in place, so that another checkout can be
    built with the same tools without seeing this workspace's packages.
    """
    ws = str(Path(workspace).resolve())
    owned = (os.path.join(ws, 'install'), os.path.join(ws, 'build'))
    out = {}
    for key, value in env.items():
        if key.startswith('COLCON_'):
            continue
        entries = value.split(os.pathsep)
        kept = [p for p in entries if not any(p == o or p.startswith(o + os.sep) for o in owned)]
        if len(kept) != len(entries):
            if not kept:
                continue
            value = os.pathsep.join(kept)
        out[key] = value
    return out


__all__ = ['RosProcess', 'executable_path', 'live_processes', 'stop_all_processes']


def start_closed_loop(start, specs, params, extra=None, on_start=None) -> dict:
    """Start the processes of a closed loop in the description's order; return {key: process}.

    ``specs``: ``actuator_bringup.run_description.closed_loop``'s NodeSpecs (or some of them). Each
    process gets the arguments the runner gives it (``ros_arguments`` with the scenario file
    ``params``, e.g. ``actuator_bringup.runner.scenario_file(name)``) and then ``extra[key]``.
    ``start``: the ``ros_process`` fixture, or any factory of its signature, called as
    ``start(package, executable, args, name=key)``. ``on_start(key, process)``, if given, runs
    after each start and before the next (e.g. a wait until a simulated drive listens).
    """
    from actuator_bringup.ros_arguments import ros_arguments

    procs = {}
    for spec in specs:
        args = ros_arguments(spec, params) + list((extra or {}).get(spec.key, ()))
        procs[spec.key] = start(spec.package, spec.executable, args, name=spec.key)
        if on_start is not None:
            on_start(spec.key, procs[spec.key])
    return procs


def wait_until(predicate, timeout: float, interval: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())


def catches_signal(pid: int, signum: int) -> bool:
    """Tell whether process ``pid`` has a handler for ``signum`` (SigCgt in /proc/<pid>/status)."""
    try:
        status = Path(f'/proc/{pid}/status').read_text()
    except OSError:
        return False
    mask = next((int(x.split()[1], 16) for x in status.splitlines() if x.startswith('SigCgt:')), 0)
    return bool(mask >> (signum - 1) & 1)


def wait_for_signal_handler(proc: RosProcess, signum: int, timeout: float = 20.0) -> None:
    """Wait until ``proc`` handles ``signum``; fail if it exits or the timeout passes first.

    Python handles SIGINT from its start but not SIGTERM: a SIGTERM handler is the entry
    point's own (``actuator_ros.early.quiet_until_running``, ``actuator_bag.entry``).
    """
    deadline = time.monotonic() + timeout
    while not catches_signal(proc.pid, signum):
        assert proc.running, f'{proc.name} exited before it handled signal {signum}'
        assert time.monotonic() < deadline, f'{proc.name} never handled signal {signum}'
        time.sleep(0.002)


def _stamp(ns: int):
    """builtin_interfaces/Time of ``ns`` (imported here: the unit set runs without ROS)."""
    from actuator_ros.conversions import ns_to_stamp

    return ns_to_stamp(ns)


#: A controller that latches at 0.05 rad and waits 50 ms for its inputs: the latch tests.
LATCHING_CONTROLLER_ARGS = [
    '--ros-args',
    '-p',
    'autostart:=true',
    '-p',
    'following_error_limit_rad:=0.05',
    '-p',
    'measurement_timeout_s:=0.05',
    '-p',
    'estimate_timeout_s:=0.05',
]


class TestNode:
    """An rclpy node of the test on its own executor: spin, wait, call services, lifecycle."""

    __test__ = False  # not a pytest test class

    def __init__(self, context, name: str):
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        self.node = Node(name, context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self._lifecycle: dict = {}

    def spin(self, seconds: float) -> None:
        """Run the node's callbacks for ``seconds``."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.005)

    def spin_in_background(self) -> threading.Thread:
        """Run the node's callbacks on a daemon thread until ``close``.

        For arrivals timed as they come while the test waits on something else.
        """
        thread = threading.Thread(target=self.executor.spin, daemon=True)
        thread.start()
        return thread

    def wait_for(self, predicate, timeout: float = 20.0, what: str = '') -> None:
        """Spin until ``predicate()`` holds; fail after ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return
            self.executor.spin_once(timeout_sec=0.01)
        raise AssertionError(f'timed out waiting for {what}')

    def wait_matched(self, publisher, subscribers: int = 1, timeout: float = 20.0) -> None:
        """Spin until ``publisher`` has matched ``subscribers`` subscriptions of other nodes.

        An event in place of a discovery sleep: a message published before the match is lost
        to that subscriber. This node's own subscriptions on the topic match at once and are
        not counted.
        """
        own = sum(s.topic_name == publisher.topic_name for s in self.node.subscriptions)
        self.wait_for(
            lambda: publisher.get_subscription_count() >= own + subscribers,
            timeout,
            f'{subscribers} subscription(s) of other nodes matched on {publisher.topic_name}',
        )

    def call(self, client, request, timeout: float = 20.0):
        """Call a service and return its response (fail when it is absent or silent)."""
        assert client.wait_for_service(timeout_sec=timeout), f'{client.srv_name} not available'
        future = client.call_async(request)
        self.wait_for(future.done, timeout, f'an answer from {client.srv_name}')
        return future.result()

    def transition(self, node_name: str, label) -> bool:
        """Request a lifecycle transition of ``node_name`` (``ros2 lifecycle set``); True if done.

        ``label``: 'configure', 'activate', 'deactivate', 'cleanup', or a Transition id.
        """
        from lifecycle_msgs.msg import Transition
        from lifecycle_msgs.srv import ChangeState

        ids = {
            'configure': Transition.TRANSITION_CONFIGURE,
            'activate': Transition.TRANSITION_ACTIVATE,
            'deactivate': Transition.TRANSITION_DEACTIVATE,
            'cleanup': Transition.TRANSITION_CLEANUP,
        }
        transition = Transition(id=label if isinstance(label, int) else ids[label])
        client = self._lifecycle_client(node_name, 'change_state', ChangeState)
        return self.call(client, ChangeState.Request(transition=transition)).success

    def lifecycle_state(self, node_name: str) -> str:
        """Return the lifecycle state label of ``node_name`` (``ros2 lifecycle get``)."""
        from lifecycle_msgs.srv import GetState

        client = self._lifecycle_client(node_name, 'get_state', GetState)
        return self.call(client, GetState.Request()).current_state.label

    def _lifecycle_client(self, node_name: str, service: str, kind):
        key = (node_name, service)
        if key not in self._lifecycle:
            self._lifecycle[key] = self.node.create_client(kind, f'/{node_name}/{service}')
        return self._lifecycle[key]

    def close(self) -> None:
        """Stop the executor and destroy the node."""
        self.executor.shutdown()
        self.node.destroy_node()


#: Depth of the harness's recording subscriptions: 10 s of a 1 kHz stream.
RECORDED_DEPTH = 10000


class Harness(TestNode):
    """A test-side node that publishes into and records from the node under test."""

    def __init__(self, context):
        from rclpy.qos import HistoryPolicy, QoSProfile
        from sensor_msgs.msg import JointState

        from actuator_msgs.msg import ControllerState, CurrentCommand, PlantTruth, StateEstimate
        from actuator_ros.qos import control_qos

        super().__init__(context, 'harness')
        qos = control_qos('realtime')
        self.joint = self.node.create_publisher(JointState, 'joint_states', qos)
        self.estimate = self.node.create_publisher(StateEstimate, 'eso/estimate', qos)
        self.qos = qos
        self.command = (
            None  # created by the first send_command: another publisher on it stops a controller
        )
        self.got = {'command': [], 'state': [], 'estimate': [], 'truth': []}
        # The recording side keeps what a stalled harness has not taken yet: with the loop's depth
        # of 10, a harness held up by a loaded machine dropped states from its own queue, and a
        # test that reads every change of status then failed (CI, 2026-12-05).
        kept = QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=RECORDED_DEPTH,
            reliability=qos.reliability,
            durability=qos.durability,
        )
        for kind, topic, key in (
            (CurrentCommand, 'current_command', 'command'),
            (ControllerState, 'controller/state', 'state'),
            (StateEstimate, 'eso/estimate', 'estimate'),
            (PlantTruth, 'plant/truth', 'truth'),
        ):
            self.node.create_subscription(kind, topic, self.got[key].append, kept)
        self.types = {
            'JointState': JointState,
            'StateEstimate': StateEstimate,
            'CurrentCommand': CurrentCommand,
        }

    def send_sample(
        self, stamp_ns: int, position: float, velocity=0.0, disturbance=0.0, estimate=True
    ) -> None:
        js = self.types['JointState'](name=['joint'], position=[position])
        js.header.stamp = _stamp(stamp_ns)
        self.joint.publish(js)  # first: an estimate counts only for a measurement seen
        if estimate:
            self.spin(0.002)
            est = self.types['StateEstimate'](
                velocity_rad_s=velocity, disturbance_rad_s2=disturbance
            )
            est.header.stamp = _stamp(stamp_ns)
            self.estimate.publish(est)

    def send_command(self, stamp_ns: int, current: float) -> None:
        if self.command is None:
            self.command = self.node.create_publisher(
                self.types['CurrentCommand'], 'current_command', self.qos
            )
            self.wait_matched(self.command)  # the node under test sees the first command
        cmd = self.types['CurrentCommand'](current_a=current)
        cmd.header.stamp = _stamp(stamp_ns)
        self.command.publish(cmd)


def now_ns(harness) -> int:
    """Return the harness node's clock [ns]."""
    return harness.node.get_clock().now().nanoseconds


def run_off(harness, start_ns: int) -> None:
    """Send 8 samples of a joint running off at a plausible 2500 rad/s^2 (52.5 mrad at 6 ms)."""
    for k in range(8):
        harness.send_sample(start_ns + k * 1_000_000, 1.25e-3 * k * (k + 1))
        harness.spin(0.002)
