# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A real-time process's Fast DDS runs over UDP, never shared memory (actuator_ros/middleware.py).

Shared memory's port check can stop a publisher, and with rclpy's GIL the whole process, for
333 ms when a peer joins (the CiA 402 driver's intermittent 321 ms stall, issue 20).
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from actuator_ros.middleware import TransportChoice, installed_profile, realtime_transport

PROFILE = Path('/share/actuator_ros/config/fastdds_realtime_loopback.xml')


def test_localhost_gets_the_loopback_udp_profile_and_a_range_that_keeps_it() -> None:
    """rmw_fastrtps builds shared memory for LOCALHOST itself: the profile replaces it."""
    env = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', 'ROS_LOCALHOST_ONLY': '1'}
    choice = realtime_transport(env, PROFILE)
    assert choice.set == {
        'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SYSTEM_DEFAULT',
        'FASTRTPS_DEFAULT_PROFILES_FILE': str(PROFILE),
    }
    assert choice.unset == ('ROS_LOCALHOST_ONLY',) and not choice.warning
    choice.apply(env)
    assert env == choice.set and 'UDPv4 on 127.0.0.1 only' in choice.note
    # the deprecated variable alone means LOCALHOST too
    assert realtime_transport({'ROS_LOCALHOST_ONLY': '1'}, PROFILE).set == choice.set


@pytest.mark.parametrize('range_', ['', 'SUBNET', 'SYSTEM_DEFAULT', 'OFF'])
def test_other_ranges_keep_fast_dds_built_in_transports_udp_only(range_: str) -> None:
    """Fast DDS honours FASTDDS_BUILTIN_TRANSPORTS when rmw does not build the transports."""
    env = {'ROS_AUTOMATIC_DISCOVERY_RANGE': range_} if range_ else {}
    choice = realtime_transport(env, PROFILE)
    assert choice.set == {'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4'} and choice.unset == ()


@pytest.mark.parametrize(
    'name',
    [
        'FASTDDS_BUILTIN_TRANSPORTS',
        'FASTRTPS_DEFAULT_PROFILES_FILE',
        'FASTDDS_DEFAULT_PROFILES_FILE',
    ],
)
def test_a_users_own_fast_dds_choice_is_kept_and_said(name: str) -> None:
    env = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', name: 'mine'}
    choice = realtime_transport(env, PROFILE)
    assert choice.set == {} and choice.unset == () and name in choice.note


def test_static_peers_on_localhost_keep_shared_memory_with_a_warning() -> None:
    env = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', 'ROS_STATIC_PEERS': '192.168.0.7'}
    choice = realtime_transport(env, PROFILE)
    assert choice.set == {} and choice.warning and '333 ms' in choice.note


def test_another_rmw_is_left_alone() -> None:
    env = {
        'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp',
        'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
    }
    assert realtime_transport(env, PROFILE) == TransportChoice()


def _shared_memory_maps(pid: int | str) -> list[str]:
    """Fast DDS shared-memory segments mapped into process ``pid``."""
    lines = Path(f'/proc/{pid}/maps').read_text().splitlines()
    return sorted({line.split()[-1] for line in lines if '/dev/shm/fastrtps' in line})


@pytest.mark.realtime
def test_a_real_time_node_talks_over_udp_to_a_localhost_peer_and_maps_no_shared_memory(
    ros_env, rclpy_context
) -> None:
    """The floor's echo (run_node, real time) answers this LOCALHOST participant, without SHM."""
    from actuator_msgs.msg import CurrentCommand
    from actuator_ros.qos import control_qos
    from ros_helpers import TestNode

    assert installed_profile().is_file()
    probe = TestNode(rclpy_context, 'middleware_probe')
    qos = control_qos('realtime')
    pongs: list = []
    ping = probe.node.create_publisher(CurrentCommand, 'floor/ping', qos)
    probe.node.create_subscription(CurrentCommand, 'floor/pong', pongs.append, qos)
    echo = subprocess.Popen(
        [sys.executable, '-m', 'actuator_bench.floor', 'echo'],
        env=ros_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        probe.wait_matched(ping)
        deadline = time.monotonic() + 20.0
        while len(pongs) < 20 and time.monotonic() < deadline:
            ping.publish(CurrentCommand())
            probe.spin(0.01)
        assert len(pongs) >= 20, 'the echo did not answer over UDP'
        # this process's LOCALHOST participant maps shared memory, so the check can see it
        assert _shared_memory_maps('self')
        assert _shared_memory_maps(echo.pid) == []
    finally:
        echo.terminate()
        output, _ = echo.communicate(timeout=20)
        probe.node.destroy_node()
    assert 'Fast DDS over UDPv4 on 127.0.0.1 only' in output, output
