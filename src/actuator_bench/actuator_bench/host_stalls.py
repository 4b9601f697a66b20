# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Host floor: how late a lone thread on a 1 ms grid wakes on this machine, with no ROS at all.

The joint's sampling thread sleeps to an absolute grid and runs one cycle per sample; when it
wakes late, every node after it is late too, and a wake-up later than the measurement timeout
(``actuator_core.limits.MEASUREMENT_TIMEOUT_S``) is a stale input for the controller. This probe
is that thread without the node: one thread, the same sleep to the same grid, under the same
scheduling (SCHED_FIFO when asked, optionally on one CPU), recording each wake-up later than a
threshold. What it finds is the machine's (the kernel's, or a hypervisor's that takes the virtual
CPU away), not the loop's; the benchmark (``bench``) runs it beside the middleware floor so a
real-time run's tracking can be read against it.

    python -m actuator_bench.host_stalls --duration 10 [--priority 51] [--cpu 0]
    python -m actuator_bench.host_stalls --until-stopped --priority 60 --cpu 1   # until SIGTERM

The second form is the tests' host probe (tests/host_probe.py): it runs beside a real-time test
and, when stopped, prints the stalls with their monotonic instants, so a test can tell a stall of
the host inside its own window from a fault of the loop.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time
from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence

from actuator_core.limits import MEASUREMENT_TIMEOUT_S

#: A wake-up this late is counted as a stall [ns]: twice the sample period, the first lateness
#: that leaves a sample without its command.
STALL_THRESHOLD_NS = 2_000_000
#: The grid's period [ns]: the joint's 1 kHz.
GRID_PERIOD_NS = 1_000_000
#: A stall longer than the controller's measurement timeout is a stale input there [ns].
TIMEOUT_NS = int(round(MEASUREMENT_TIMEOUT_S * 1e9))


@dataclass
class StallCount:
    """Wake-ups of a grid thread later than ``threshold_ns``: how many, how late, when."""

    threshold_ns: int = STALL_THRESHOLD_NS
    timeout_ns: int = TIMEOUT_NS
    wakeups: int = 0
    stalls: list = field(default_factory=list)  # (grid instant since start [ns], lateness [ns])
    start_ns: int = 0  # the grid's start on its clock (run_grid)
    end_ns: int = 0  # when the grid ended on its clock (run_grid)

    def update(self, instant_ns: int, late_ns: int) -> None:
        """Count one wake-up at grid ``instant_ns`` that came ``late_ns`` after it.

        The instants a stall swallowed (a late wake-up runs them at once) count as one stall:
        only a wake-up after the thread slept, or the first of a run of late ones, is a new one.
        """
        self.wakeups += 1
        if late_ns <= self.threshold_ns:
            return
        if self.stalls:
            last_instant, last_late = self.stalls[-1]
            if instant_ns - last_instant < last_late:  # still catching up on the same stall
                return
        self.stalls.append((instant_ns, late_ns))

    def figures(self, duration_s: float, prefix: str) -> dict[str, float]:
        """Stalls per minute, the longest [ms], and those beyond the measurement timeout."""
        longest = max((late for _, late in self.stalls), default=0)
        return {
            f'{prefix}_stalls_per_min': 60.0 * len(self.stalls) / duration_s,
            f'{prefix}_stall_max_ms': longest * 1e-6,
            f'{prefix}_beyond_timeout_per_min': 60.0
            * sum(late > self.timeout_ns for _, late in self.stalls)
            / duration_s,
        }


def run_grid(
    duration_s: float,
    count: StallCount,
    period_ns: int = GRID_PERIOD_NS,
    clock: Callable[[], int] = time.monotonic_ns,
    sleep: Callable[[float], None] = time.sleep,
    stopped: Callable[[], bool] = lambda: False,
) -> StallCount:
    """Sleep to each instant of a ``period_ns`` grid for ``duration_s``; count late wake-ups.

    As the joint's sampling thread does (actuator_ros.joint_node): absolute instants from one
    start, a late wake-up runs the instants it missed at once. ``stopped`` ends the grid early
    (checked at every instant); ``count.start_ns`` keeps the start on ``clock``.
    """
    start = count.start_ns = clock()
    end = start + int(duration_s * 1e9)
    k = 0
    while True:
        k += 1
        instant = start + k * period_ns
        if instant > end or stopped():
            count.end_ns = clock()
            return count
        wait = instant - clock()
        if wait > 0:
            sleep(wait * 1e-9)
        count.update(instant - start, clock() - instant)


def apply_scheduling(priority: int, cpu: Optional[int]) -> Optional[str]:
    """SCHED_FIFO ``priority`` (0: leave it) and one CPU (None: any); the refusal, if any."""
    try:
        if cpu is not None:
            os.sched_setaffinity(0, {cpu})
        if priority:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, ValueError) as exc:
        return f'scheduling refused ({exc}): measured as this process is'
    return None


def build_parser() -> argparse.ArgumentParser:
    """Arguments of ``python -m actuator_bench.host_stalls``."""
    parser = argparse.ArgumentParser(
        prog='host_stalls',
        description='Count the late wake-ups of a lone 1 kHz grid thread (no ROS).',
    )
    parser.add_argument('--duration', type=float, default=10.0, help='seconds to run')
    parser.add_argument(
        '--until-stopped',
        action='store_true',
        help='run until SIGTERM or SIGINT (at most --duration), then print the figures and '
        'each stall with its monotonic instant',
    )
    parser.add_argument(
        '--priority', type=int, default=0, help='SCHED_FIFO priority (0: normal scheduling)'
    )
    parser.add_argument('--cpu', type=int, default=None, help='run on this CPU only')
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the grid and print one line of figures (JSON), the stalls after it."""
    args = build_parser().parse_args(argv)
    if not 0.1 <= args.duration <= 3600.0:
        print('host_stalls: --duration must be in [0.1, 3600] s', file=sys.stderr)
        return 2
    if not 0 <= args.priority <= 99:
        print('host_stalls: --priority must be in [0, 99]', file=sys.stderr)
        return 2
    refused = apply_scheduling(args.priority, args.cpu)
    if refused:
        print(f'host_stalls: {refused}', file=sys.stderr)
    stop = []
    if args.until_stopped:
        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, lambda *_: stop.append(True))
        print('host_stalls: running', file=sys.stderr, flush=True)  # the probe waits for it
    count = run_grid(args.duration, StallCount(), stopped=lambda: bool(stop))
    seconds = max((count.end_ns - count.start_ns) * 1e-9, 1e-3)
    figures: dict[str, object] = {**count.figures(seconds, 'host')}
    figures['host_wakeups'] = float(count.wakeups)
    if args.until_stopped:
        figures['host_seconds'] = seconds
        figures['host_fifo'] = bool(args.priority) and not refused
        figures['host_stalls_ns'] = [[count.start_ns + i, late] for i, late in count.stalls]
    print(json.dumps(figures), flush=True)
    for instant, late in count.stalls:
        print(f'stall at {instant * 1e-9:.3f} s: {late * 1e-6:.1f} ms late', file=sys.stderr)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
