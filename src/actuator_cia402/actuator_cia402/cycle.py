# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The driver's cycle thread: SYNC on an absolute grid of the system clock, as ros2_control's loop.

Each cycle k at t_k = start + k * period: take the command to apply (the gate's hold), write
RPDO1 and send SYNC (the drive answers with TPDO1/TPDO2 sampled at the SYNC), wait at most
``wait_s`` for TPDO1, hand the sample stamped t_k to ``on_sample``. A wake-up later than one
period skips the missed cycles (ros2_control's overrun handling: no replay) and counts them.
The CPU time of each cycle (thread time: the TPDO wait is not counted) and its wake-up
lateness are kept for the diagnostics and the benchmark. ROS-free.
"""

from __future__ import annotations

import threading
import time
from typing import Callable, Optional

import numpy as np

from actuator_cia402.master import Cia402Master, DriveFault, Feedback

#: Cycles kept for the medians (about 4 s at 1 kHz).
HISTORY = 4096


class CycleStats:
    """Counts and recent per-cycle figures of the cycle thread."""

    def __init__(self) -> None:
        """Empty statistics."""
        self.cycles = 0
        self.missed_feedback = 0
        self.overruns = 0
        self.skipped_cycles = 0
        self.cpu_ns = np.zeros(HISTORY, dtype=np.int64)
        self.late_ns = np.zeros(HISTORY, dtype=np.int64)
        self.wall_ns = np.zeros(HISTORY, dtype=np.int64)

    def record(self, cpu_ns: int, late_ns: int, wall_ns: int) -> None:
        """Keep one cycle's CPU time, wake-up lateness and wall time (SYNC to TPDO1 handled)."""
        i = self.cycles % HISTORY
        self.cpu_ns[i], self.late_ns[i], self.wall_ns[i] = cpu_ns, late_ns, wall_ns
        self.cycles += 1

    def medians_us(self) -> dict[str, float]:
        """Median and 99th percentile of CPU per cycle.

        Lateness and cycle wall time over the kept cycles [us].
        """
        n = min(self.cycles, HISTORY)
        out = {}
        for name, values in (
            ('cpu', self.cpu_ns),
            ('late', self.late_ns),
            ('cycle_wall', self.wall_ns),
        ):
            kept = values[:n] / 1e3
            out[f'{name}_p50_us'] = float(np.median(kept)) if n else float('nan')
            out[f'{name}_p99_us'] = float(np.percentile(kept, 99)) if n else float('nan')
        return out


class SyncCycle:
    """Runs the master's cycle on a thread until stopped, faulted, silent or done."""

    def __init__(
        self,
        master: Cia402Master,
        period_s: float,
        wait_s: float,
        feedback_timeout_s: float,
        command: Callable[[int], tuple[int, float]],
        on_sample: Callable[[int, Feedback], None],
        stop_after_s: float = 0.0,
    ):
        """``command(t_ns)`` -> (controlword, current [A]); ``on_sample(stamp_ns, feedback)``."""
        self.master = master
        self.period_ns = int(round(period_s * 1e9))
        self.wait_s = wait_s
        self.feedback_timeout_ns = int(round(feedback_timeout_s * 1e9))
        self.command, self.on_sample = command, on_sample
        self.stop_after_cycles = int(round(stop_after_s / period_s)) if stop_after_s > 0 else 0
        self.stats = CycleStats()
        self.ended: Optional[str] = None  # why the loop ended: 'stopped', 'done', 'fault', 'error'
        self.fault: Optional[DriveFault] = None
        self.start_ns: Optional[int] = None
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None

    def start(self) -> None:
        """Start the thread; sample 0 is on the next whole period of the system clock plus one."""
        now = time.time_ns()
        self.start_ns = (now // self.period_ns + 2) * self.period_ns
        self._thread = threading.Thread(target=self._run, name='cia402-cycle', daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 1.0) -> None:
        """Stop the thread and wait for it."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)

    @property
    def running(self) -> bool:
        """The thread is alive."""
        return self._thread is not None and self._thread.is_alive()

    def _run(self) -> None:
        """Run the loop.

        An exception ends it with ``ended = 'error'`` and the reason in ``fault``.
        """
        try:
            self._loop()
        except Exception as exc:  # noqa: BLE001 - reported by the node, never lost with the thread
            self.fault = DriveFault(0, f'cycle thread failed: {exc!r}', 'driver')
            self.ended = 'error'

    def _loop(self) -> None:
        """Sleep to t_k, one cycle, repeat (see the module docstring)."""
        k = 0
        last_feedback_ns = self.start_ns
        master, stats = self.master, self.stats
        while not self._stop.is_set():
            t_k = self.start_ns + k * self.period_ns
            wait_ns = t_k - time.time_ns()
            if wait_ns > 0:
                time.sleep(wait_ns * 1e-9)
            now = time.time_ns()
            late = now - t_k
            if late >= self.period_ns:  # overrun: jump to the present cycle
                skipped = late // self.period_ns
                stats.overruns += 1
                stats.skipped_cycles += int(skipped)
                k += int(skipped)
                t_k = self.start_ns + k * self.period_ns
                late = now - t_k
            cpu0, wall0 = time.thread_time_ns(), time.perf_counter_ns()
            controlword, current_a = self.command(t_k)
            feedback = master.cycle(controlword, current_a, self.wait_s)
            if feedback is not None:
                last_feedback_ns = t_k
                self.on_sample(t_k, feedback)
            else:
                stats.missed_feedback += 1
            stats.record(time.thread_time_ns() - cpu0, late, time.perf_counter_ns() - wall0)
            if master.fault is not None:
                self.fault, self.ended = master.fault, 'fault'
                return
            if t_k - last_feedback_ns > self.feedback_timeout_ns:
                self.fault = DriveFault(
                    0,
                    f'no TPDO from the drive for {(t_k - last_feedback_ns) / 1e6:.0f} ms '
                    '(silent bus or drive)',
                    'feedback timeout',
                )
                self.ended = 'fault'
                return
            k += 1
            if self.stop_after_cycles and k >= self.stop_after_cycles:
                self.ended = 'done'
                return
        self.ended = 'stopped'
