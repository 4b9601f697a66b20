# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Which TPDO1 answers which SYNC, for a SYNC producer. ROS-free; the joint holds one.

TPDO1 carries no SYNC counter, but a drive answers its SYNCs in order (synchronous PDOs,
CiA 301): TPDO1 number n answers SYNC number n, less the answers the drive dropped. So a late
answer only counts, and is never taken for the next SYNC's (which put a position one period old
under a newer stamp). A dropped answer and a drive one period late look the same on the bus:
the count is taken as dropped once it has stayed behind for ``TPDO_LAG_CYCLES`` cycles in a
row while answers kept coming (a late drive catches up instead), and then only by the least it
stayed behind in those cycles (a late answer on top of a drop is not a drop).
"""

from __future__ import annotations

#: Cycles in a row whose TPDO1 count stays behind while answers come: those were dropped. A
#: drive late this many SYNCs in a row would be taken for one that dropped answers; a drop
#: costs this many cycles without a sample (the controller waits 7 before it resyncs).
TPDO_LAG_CYCLES = 5


class AnswerCount:
    """The answers owed for the SYNCs sent, and those judged dropped."""

    def __init__(self, lag_cycles: int = TPDO_LAG_CYCLES):
        """Nothing sent, nothing owed."""
        self.lag_cycles = lag_cycles
        self.lost = 0  # SYNCs whose answer was judged dropped (or came before a restart)
        self.dropped = 0  # answers judged dropped since construction
        self._lagging = 0  # cycles in a row behind while answers came
        self._least = 0  # the least the count was behind in those cycles

    def restart(self, sent: int, received: int) -> None:
        """Count every SYNC sent so far as answered (a new run)."""
        self.lost = sent - received
        self._lagging = 0

    def owed(self, sent: int, received: int) -> int:
        """Return the answers still owed for ``sent`` SYNCs after ``received`` TPDO1s."""
        return sent - received - self.lost

    def judge(self, sent: int, received: int, received_at_sync: int) -> bool:
        """Return True when the newest TPDO1 answers SYNC number ``sent``.

        Called once per cycle at its deadline; ``received_at_sync``: TPDO1s received when
        that SYNC went out.
        """
        behind = self.owed(sent, received)
        if behind < 0:  # an answer judged dropped came after all
            self.lost, behind = sent - received, 0
        if behind == 0:
            self._lagging = 0
            return True
        if received == received_at_sync:  # nothing came: a silent or late drive, not a drop
            return False
        self._lagging += 1
        self._least = behind if self._lagging == 1 else min(self._least, behind)
        if self._lagging < self.lag_cycles:
            return False
        self.dropped += self._least
        self.lost += self._least
        self._lagging = 0
        return behind == self._least  # then the newest answers this SYNC
