# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The host floor (actuator_bench.host_stalls): late wake-ups of a lone grid thread, counted."""

import json
import subprocess
import sys

import pytest

from actuator_bench.host_stalls import StallCount, run_grid

MS = 1_000_000


class FakeHost:
    """A monotonic clock and a sleep that wakes late at the instants it is told."""

    def __init__(self, late_at_ns: dict):
        self.now = 0
        self.late_at_ns = dict(late_at_ns)  # sleep ending at this instant: wake this much later

    def clock(self) -> int:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += int(round(seconds * 1e9))
        self.now += self.late_at_ns.pop(self.now, 0)


def test_a_stall_counts_once_however_many_instants_it_swallowed():
    host = FakeHost({5 * MS: 8 * MS, 20 * MS: 3 * MS})
    count = run_grid(0.03, StallCount(), clock=host.clock, sleep=host.sleep)
    assert count.wakeups == 30
    assert count.stalls == [(5 * MS, 8 * MS), (20 * MS, 3 * MS)]
    f = count.figures(0.03, 'host')
    assert f['host_stalls_per_min'] == pytest.approx(60.0 * 2 / 0.03)
    assert f['host_stall_max_ms'] == pytest.approx(8.0)
    assert f['host_beyond_timeout_per_min'] == pytest.approx(60.0 / 0.03)  # 8 ms > 7 ms only


def test_lateness_up_to_the_threshold_is_no_stall_and_a_quiet_host_has_none():
    host = FakeHost({4 * MS: 2 * MS})  # exactly the threshold
    count = run_grid(0.01, StallCount(), clock=host.clock, sleep=host.sleep)
    assert count.wakeups == 10 and count.stalls == []
    assert count.figures(0.01, 'h') == {
        'h_stalls_per_min': 0.0,
        'h_stall_max_ms': 0.0,
        'h_beyond_timeout_per_min': 0.0,
    }


def test_a_second_stall_right_after_the_catch_up_is_a_new_one():
    count = StallCount()
    for instant, late in ((1 * MS, 3 * MS), (2 * MS, 2 * MS), (3 * MS, 1 * MS), (4 * MS, 5 * MS)):
        count.update(instant, late)
    assert count.stalls == [(1 * MS, 3 * MS), (4 * MS, 5 * MS)]


@pytest.mark.slow
def test_the_command_line_prints_its_figures_and_refuses_a_bad_duration():
    done = subprocess.run(
        [sys.executable, '-m', 'actuator_bench.host_stalls', '--duration', '0.2'],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    figures = json.loads(done.stdout)
    assert figures['host_wakeups'] == 200
    assert set(figures) >= {'host_stalls_per_min', 'host_stall_max_ms'}
    bad = subprocess.run(
        [sys.executable, '-m', 'actuator_bench.host_stalls', '--duration', '0'],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 2 and bad.stderr.count('\n') == 1 and '--duration' in bad.stderr
