# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Signals before a node runs: exit 0 quietly, never a KeyboardInterrupt traceback from an import.

The entry point of every executable calls ``quiet_until_running`` before it imports rclpy
(0.3-0.5 s of imports during which Ctrl-C used to print a traceback); ``runner.run_node``
then installs the handlers that stop the running node cleanly.
"""

from __future__ import annotations

import os
import signal


def quiet_until_running() -> None:
    """Make SIGINT and SIGTERM end the process at once with exit code 0.

    Until the node installs its own handlers.
    """
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: os._exit(0))
