# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Entry point of ``plant_node``.

Signals answered quietly from the first instant, then the node's imports.
"""

from actuator_ros.early import quiet_until_running


def main() -> int:
    """Quiet signals, import the node module (rclpy: 0.3-0.5 s), run it."""
    quiet_until_running()
    from actuator_plant.plant_node import main as run

    return run()
