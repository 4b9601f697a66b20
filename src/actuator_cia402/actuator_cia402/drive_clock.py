# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The simulated drive's time base (ROS- and canopen-free): the periods a SYNC or the clock passes.

A drive's cycle is its SYNC's: each SYNC passes the idle periods before it, then one period
with the cycle (RPDO latched, TPDOs sent). With the CiA 301 SYNC counter (0x1019) the SYNCs
say how many periods passed, however late the drive's process took one; with plain SYNCs the
drive phase-locks its period grid so that SYNCs fall mid-period and counts on that grid, which
holds for SYNCs less than half a period late. Without SYNCs for ``FREE_RUN_AFTER_PERIODS`` the
drive's own clock steps drive time (a joint left to itself keeps moving). ``SimulatedDrive``
steps the periods this returns; tests/test_cia402_sync.py drives both.
"""

from __future__ import annotations

#: Longest gap caught up at once [periods]; beyond it the joint model's time is lost.
MAX_CATCH_UP_PERIODS = 1000
#: Silence after which a SYNC re-locks the drive's cycle at once (a new master) [periods].
SYNC_RELOCK_PERIODS = 100
#: Share of each SYNC's phase error the drive's cycle follows (a first-order phase lock).
SYNC_LOCK_GAIN = 1.0 / 16.0
#: SYNC silence after which the drive's clock steps drive time itself [periods].
FREE_RUN_AFTER_PERIODS = 10


class DriveClock:
    """Drive time's period grid on the monotonic clock, locked to the SYNCs it takes."""

    def __init__(self, period_ns: int, t0_ns: int) -> None:
        """Grid of ``period_ns`` starting at ``t0_ns`` (monotonic) until a SYNC locks it."""
        self.period_ns = period_ns
        self.t0_ns = t0_ns
        self.locked_sync_ns: int | None = None  # monotonic time of the last SYNC taken
        self.last_counter: int | None = None  # the counter the last SYNC carried
        self.sync_period = 0  # drive time after the last SYNC's cycle [periods]
        self.counted_syncs = 0  # SYNCs whose counter told the periods that passed

    def idle_periods(self, now_ns: int, periods: int, margin: int) -> int:
        """Return the periods to step without a cycle: drive time ``margin`` behind the grid."""
        due = (now_ns - self.t0_ns) // self.period_ns
        return max(0, min(MAX_CATCH_UP_PERIODS, due - margin - periods))

    def free_running(self, now_ns: int) -> bool:
        """Whether no SYNC came for ``FREE_RUN_AFTER_PERIODS``: the clock steps drive time."""
        last = self.locked_sync_ns
        return last is None or now_ns - last > FREE_RUN_AFTER_PERIODS * self.period_ns

    def on_sync(self, now_ns: int, counter: int | None, overflow: int, periods: int) -> int:
        """Return the idle periods before the cycle of a SYNC taken at ``now_ns``.

        ``counter``: the SYNC's counter byte (None: a plain SYNC); ``overflow``: 0x1019;
        ``periods``: drive time so far. Call ``cycle_done`` after its cycle.
        """
        counted = self._counted(counter, overflow, relock=self._lock(now_ns))
        if counted is None:
            return self.idle_periods(now_ns, periods, margin=0)
        self.counted_syncs += 1  # the idle periods it says passed, less those the clock stepped
        return max(0, min(MAX_CATCH_UP_PERIODS, self.sync_period + counted - 1 - periods))

    def cycle_done(self, periods: int) -> None:
        """Note drive time after a SYNC's cycle [periods]."""
        self.sync_period = periods

    def _lock(self, now_ns: int) -> bool:
        """Move the grid so that SYNCs fall mid-period (a phase lock); True: locked anew.

        The first SYNC, and the first after a silence of ``SYNC_RELOCK_PERIODS``, sets the
        phase at once; each later one moves it by ``SYNC_LOCK_GAIN`` of its error, so the
        jitter of single SYNCs averages out.
        """
        error_ns = (now_ns - self.t0_ns) % self.period_ns - self.period_ns // 2
        last = self.locked_sync_ns
        relock = last is None or now_ns - last > SYNC_RELOCK_PERIODS * self.period_ns
        self.t0_ns += error_ns if relock else round(error_ns * SYNC_LOCK_GAIN)
        self.locked_sync_ns = now_ns
        return relock

    def _counted(self, counter: int | None, overflow: int, relock: bool) -> int | None:
        """Return the periods since the last SYNC by its counter; None without one."""
        last, self.last_counter = self.last_counter, counter
        if counter is None or last is None or relock:
            return None
        return (counter - last) % overflow or overflow
