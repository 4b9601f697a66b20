# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Entry points of ``recorder`` and ``player``.

Signals are answered quietly from the first instant, then come the imports.
"""

from actuator_ros.early import quiet_until_running


def recorder() -> int:
    """Quiet signals, import the recorder (rclpy: 0.3-0.5 s), run it.

    The recorder installs its own stop handling.
    """
    quiet_until_running()
    from actuator_bag.recorder_node import main

    return main()


def player() -> int:
    """Quiet signals, import the player (rclpy: 0.3-0.5 s), run it.

    The player installs its own stop handling.
    """
    quiet_until_running()
    from actuator_bag.player_node import main

    return main()
