# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Entry point of ``loop_container``: signals answered quietly from the first instant."""

from actuator_ros.early import quiet_until_running


def main() -> int:
    """Quiet signals, import the container (rclpy: 0.3-0.5 s), run it."""
    quiet_until_running()
    from actuator_bringup.container import main as run

    return run()
