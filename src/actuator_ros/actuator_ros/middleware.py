# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The middleware transport of a real-time process: Fast DDS over UDP, never shared memory.

Fast DDS's shared-memory transport opens a peer's port on the first send to it and checks the
port's listeners; a check that finds a listener idle sleeps ``healthy_check_timeout_ms / 3`` =
333 ms before it looks again (Fast DDS 2.14, ``SharedMemGlobal::Port::healthy_check``, 1000 ms
by default). In the asynchronous publication mode the sending thread does this while it holds the
writer's flow controller, and every publish on a full KEEP_LAST history waits for that lock; in
the synchronous mode the publishing thread does it itself; rclpy holds the GIL inside
``rcl_publish``. So when a peer joins or rejoins (a restarted node, a
recorder, ``ros2 topic echo``), the joint's sampling thread and every other thread of its process
could stop for 321-333 ms: measured here with py-spy on the CiA 402 driver (its sampling thread
in ``FlowControllerImpl::remove_change``, waiting on the lock), after which the drive's
heartbeat consumer rightly quick-stopped. Over UDP (loopback) one hop costs the same here (10 s
at 1 kHz, SCHED_FIFO: p50 125-130 us against 127-129 us), with no such check.

rmw_fastrtps builds its own transports (shared memory and UDP) for
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and ignores ``FASTDDS_BUILTIN_TRANSPORTS`` then, so a
LOCALHOST process gets the same setup from a profile without shared memory
(``share/actuator_ros/config/fastdds_realtime_loopback.xml``) and the range SYSTEM_DEFAULT, which
keeps the profile. Other ranges keep Fast DDS's built-in transports, UDPv4 only. A Fast DDS
setting the user made (a profile file, the built-in transports) is left as it is.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

#: The file name of the loopback UDP profile in share/actuator_ros/config.
PROFILE_NAME = 'fastdds_realtime_loopback.xml'
#: Variables by which a user chooses Fast DDS's transports; any of them set: left alone.
USER_CHOICES = (
    'FASTDDS_BUILTIN_TRANSPORTS',
    'FASTRTPS_DEFAULT_PROFILES_FILE',
    'FASTDDS_DEFAULT_PROFILES_FILE',
)
#: Fast DDS's own default transports (shared memory and UDP), as a user's choice that
#: ``realtime_transport`` keeps (the benchmark's shared-memory variant). With the range LOCALHOST
#: rmw_fastrtps builds the same pair itself.
SHARED_MEMORY_ENVIRONMENT = {'FASTDDS_BUILTIN_TRANSPORTS': 'DEFAULT'}
#: The rmw implementations this applies to (Fast DDS).
FASTDDS_RMWS = ('rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp')


@dataclass(frozen=True)
class TransportChoice:
    """Environment changes before rclpy.init, and the line the node logs about them."""

    set: dict = field(default_factory=dict)
    unset: tuple = ()
    note: str = ''
    warning: bool = False  # shared memory stays although the loop is real time

    def apply(self, environ) -> None:
        """Make the changes in ``environ`` (os.environ: rmw reads it at rclpy.init)."""
        for name in self.unset:
            environ.pop(name, None)
        environ.update(self.set)


def realtime_transport(environ: Mapping[str, str], profile: Path) -> TransportChoice:
    """Return the changes that make a real-time process's Fast DDS use UDP only."""
    rmw = environ.get('RMW_IMPLEMENTATION', '') or 'rmw_fastrtps_cpp'  # Jazzy's default
    if rmw not in FASTDDS_RMWS:
        return TransportChoice()
    chosen = [name for name in USER_CHOICES if environ.get(name)]
    if chosen:
        return TransportChoice(
            note=f'Fast DDS transports as the environment sets them ({", ".join(chosen)})'
        )
    localhost = environ.get('ROS_LOCALHOST_ONLY') == '1' or (
        environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '').upper() == 'LOCALHOST'
    )
    if not localhost:
        return TransportChoice(
            set={'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4'},
            note='Fast DDS over UDPv4 only (no shared memory: its port check can stop a '
            'publisher for 333 ms when a peer joins)',
        )
    if environ.get('ROS_STATIC_PEERS', '').strip():
        return TransportChoice(
            warning=True,
            note='Fast DDS keeps shared memory: ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST with '
            'ROS_STATIC_PEERS has no UDP-only profile here, and a peer joining can then stop '
            'this process for 333 ms (set FASTDDS_BUILTIN_TRANSPORTS=UDPv4 with the range '
            'SUBNET, or a profile of your own)',
        )
    return TransportChoice(
        set={
            'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SYSTEM_DEFAULT',
            'FASTRTPS_DEFAULT_PROFILES_FILE': str(profile),
        },
        unset=('ROS_LOCALHOST_ONLY',),
        note=f'Fast DDS over UDPv4 on 127.0.0.1 only ({profile.name}: the LOCALHOST range '
        'without shared memory, whose port check can stop a publisher for 333 ms when a peer '
        'joins)',
    )


def installed_profile() -> Path:
    """Return the installed loopback UDP profile (share/actuator_ros/config)."""
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory('actuator_ros')) / 'config' / PROFILE_NAME
