# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What each controller status code means: the one place.

ControllerState.msg carries the same numbers. A test checks these against the message constants, so
the two cannot drift apart.
"""

from __future__ import annotations

from enum import IntEnum


class Status(IntEnum):
    """Loop health of one control sample (``ControllerState.status``)."""

    OK = 0  #: closed-loop control, the command is the law's output
    WAITING = 1  #: no measurement or estimate yet (start-up): 0 A, safe stop
    STALE_MEASUREMENT = 2  #: the newest measurement is older than its timeout: 0 A, safe stop
    STALE_ESTIMATE = 3  #: the newest estimate is older than its timeout: 0 A, safe stop
    INVALID_INPUT = 4  #: this sample's measurement or estimate was refused: 0 A, safe stop
    LATCHED = 5  #: non-finite output or following error beyond the limit: 0 A until reset
    RESYNC = 6  #: the sensor's time base jumped (a restarted driver): 0 A and brake until
    #: the observer has converged on the new samples, then control restarts
    CONFLICT = 7  #: more than one publisher feeds a control input: 0 A until one is left
    INACTIVE = 8  #: the node is not active (lifecycle): it commands nothing but 0 A
    RECOVERING = 9  #: the law runs, but |e| is outside the prescribed envelope, its command has
    #: sat at the current limit for more than AT_LIMIT_SAMPLES, or the loop is within
    #: RECOVERY_SAMPLES of a restart after a gap or a resync: never OK meanwhile

    @property
    def controlled(self) -> bool:
        """The command is the law's output (OK, RECOVERING)."""
        return self in CONTROLLED

    @property
    def safe_stop(self) -> bool:
        """Default of the command's ``safe_stop``: set on every status the law did not run.

        The controller's stale-input answer is graded (actuator_core.assembly): its first
        samples are 0 A without the brake; the sample says so itself.
        """
        return self not in CONTROLLED


#: Statuses whose command is the law's output.
CONTROLLED = (Status.OK, Status.RECOVERING)
