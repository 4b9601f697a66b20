# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""One time base for master and drive: which TPDO1 answers which SYNC, and drive time by the SYNC.

ROS-free, no bus: ``answers.AnswerCount`` message by message, and ``SimulatedDrive._on_sync``
with a hand-driven monotonic clock.
"""

from __future__ import annotations

import pytest

from actuator_cia402 import profile as p
from actuator_cia402.answers import TPDO_LAG_CYCLES, AnswerCount
from actuator_cia402.scaling import Scaling
from actuator_core import limits


def cycles(count: AnswerCount, arrivals: list[int]) -> list[bool]:
    """One SYNC per cycle; ``arrivals[k]`` TPDO1s come in cycle k; the judgement of each."""
    sent = received = 0
    out = []
    for arrived in arrivals:
        sent += 1
        at_sync = received
        received += arrived
        out.append(count.judge(sent, received, at_sync))
    return out


def test_answers_in_time_are_each_their_syncs():
    assert cycles(AnswerCount(), [1] * 10) == [True] * 10


def test_a_late_answer_counts_and_never_stands_in_for_the_next_syncs():
    # SYNC 3's answer comes with SYNC 4's; then SYNCs 6 and 7 are answered late in a row.
    # Before: the lone answer in cycles 4 and 7 was taken for their own SYNC's (a period old).
    judged = cycles(AnswerCount(), [1, 1, 0, 2, 1, 0, 1, 2, 1])
    assert judged == [True, True, False, True, True, False, False, True, True]


def test_a_dropped_answer_is_taken_as_dropped_after_the_lag_cycles():
    count = AnswerCount()
    judged = cycles(count, [1, 0] + [1] * (TPDO_LAG_CYCLES + 3))
    # cycles 2..: one behind while answers come; judged dropped in the fifth, then in time
    assert judged == [True, False] + [False] * (TPDO_LAG_CYCLES - 1) + [True] * 4
    assert count.dropped == 1 and count.lost == 1


def test_a_late_answer_on_top_of_a_drop_is_not_a_drop():
    # A drop, then SYNC 5's answer late (with SYNC 6's): two behind once, one behind otherwise.
    count = AnswerCount()
    judged = cycles(count, [1, 0, 1, 1, 0, 2, 1, 1])
    assert judged[-1] is True and count.dropped == 1  # the least it stayed behind: one


def test_an_answer_judged_dropped_that_comes_after_all_corrects_the_count():
    count = AnswerCount()
    cycles(count, [1, 0] + [1] * TPDO_LAG_CYCLES)  # judged dropped
    assert count.lost == 1
    assert count.judge(8, 8, 6) is True and count.lost == 0  # two came in cycle 8: it was late


def test_a_restart_counts_every_sync_so_far_as_answered():
    count = AnswerCount()
    count.restart(sent=40, received=31)  # SYNCs before the drive was operational
    assert count.owed(41, 31) == 1 and count.judge(41, 32, 31) is True


@pytest.mark.parametrize('phase', [0.02, 0.5, 0.98])
def test_the_simulated_drive_locks_its_cycle_to_the_sync_and_takes_one_period_per_sync(
    monkeypatch, phase
):
    """SYNCs that jitter by a fifth of a period, whatever their phase against the drive's clock.

    Before, the drive counted periods on its own grid: SYNCs near its period boundary took two
    periods or none by turns, a measurement step the observer refused.
    """
    from actuator_cia402 import sim_drive
    from actuator_cia402.sim_drive_main import default_eds

    scaling = Scaling(4096, limits.NOMINAL_GEAR_RATIO, 1.05, 10.0, 0.105)
    drive = sim_drive.SimulatedDrive(default_eds(), 1, scaling, 1e-3)  # not on a bus
    period = drive.period_ns
    base = drive.clock.t0_ns  # the drive's own period grid starts here
    now = [base]
    monkeypatch.setattr(sim_drive.time, 'monotonic_ns', lambda: now[0])
    jitter = [0, 200_000, -150_000, 180_000, 0, -200_000, 120_000, 200_000, -200_000, 50_000]
    steps = []
    for k in range(200):
        now[0] = base + (10 + k) * period + int(phase * period) + jitter[k % len(jitter)]
        before = drive.syncs
        drive._on_sync(0x80, b'', 0.0)
        steps.append(drive.syncs - before)
    assert steps[0] >= 1 and all(step == 1 for step in steps[1:]), steps
    now[0] += 5 * period  # a master that skipped four SYNCs: the four idle periods pass
    before = drive.syncs
    drive._on_sync(0x80, b'', 0.0)
    assert drive.syncs - before == 5


def test_with_the_sync_counter_the_drive_takes_one_period_per_sync_however_late_it_came(
    monkeypatch,
):
    """The drive's process late by most of a period (a loaded host), SYNCs counted (0x1019).

    Without the counter a SYNC taken more than half a period late looks like a skipped one
    followed by an on-time one: drive time ran a period ahead of the master's stamps for good.
    """
    from actuator_cia402 import sim_drive
    from actuator_cia402.sim_drive_main import default_eds

    scaling = Scaling(4096, limits.NOMINAL_GEAR_RATIO, 1.05, 10.0, 0.105)
    drive = sim_drive.SimulatedDrive(default_eds(), 1, scaling, 1e-3)  # not on a bus
    overflow = p.SYNC_COUNTER_MAX
    od = drive.od[p.SYNC_COUNTER_OVERFLOW]
    drive._on_write(p.SYNC_COUNTER_OVERFLOW, 0, od, od.encode_raw(overflow))
    period, base = drive.period_ns, drive.clock.t0_ns
    now = [base]
    monkeypatch.setattr(sim_drive.time, 'monotonic_ns', lambda: now[0])
    late = [0, 800_000, 100_000, 0, 700_000, 750_000, 0, 50_000]  # taken late, in order
    steps = []
    for k in range(500):  # past the counter's overflow
        now[0] = base + (10 + k) * period + late[k % len(late)]
        before = drive.syncs
        drive._on_sync(0x80, bytes((k % overflow + 1,)), 0.0)
        steps.append(drive.syncs - before)
    assert all(step == 1 for step in steps[1:]), steps
    k += 4  # three SYNCs the master skipped (its host), the fourth taken 0.9 period late
    now[0] = base + (10 + k) * period + 900_000
    before = drive.syncs
    drive._on_sync(0x80, bytes((k % overflow + 1,)), 0.0)
    assert drive.syncs - before == 4


def test_the_drive_clock_counts_across_the_counter_overflow_and_relocks_after_a_silence():
    """DriveClock alone: the counter's wrap, SYNCs taken late, the clock's free run, a relock."""
    from actuator_cia402.drive_clock import FREE_RUN_AFTER_PERIODS, SYNC_RELOCK_PERIODS, DriveClock

    period = 1_000_000
    clock = DriveClock(period, t0_ns=0)
    now = 10 * period + period // 2
    assert clock.free_running(now)  # no SYNC yet: the clock steps drive time
    periods = clock.on_sync(now, counter=239, overflow=240, periods=0) + 1
    assert periods == 11 and clock.counted_syncs == 0  # the first SYNC locks; the grid counts
    clock.cycle_done(periods)
    # (counter, the SYNC's period, how late the drive took it [ns]): 240 wraps to 1, 2 skipped
    for counter, k, late_ns in ((240, 11, 900_000), (3, 14, 0), (4, 15, 450_000)):
        now = k * period + period // 2 + late_ns
        periods += clock.on_sync(now, counter, 240, periods) + 1
        clock.cycle_done(periods)
    assert periods == 11 + 1 + 3 + 1 and clock.counted_syncs == 3
    assert not clock.free_running(now + FREE_RUN_AFTER_PERIODS * period)
    assert clock.free_running(now + (FREE_RUN_AFTER_PERIODS + 1) * period)
    # after a silence the next SYNC locks anew: its counter is not trusted against the old one
    now += 2 * SYNC_RELOCK_PERIODS * period
    periods += clock.idle_periods(now, periods, margin=1)  # what the clock thread stepped
    assert clock.on_sync(now, counter=7, overflow=240, periods=periods) == 1
    assert clock.counted_syncs == 3
