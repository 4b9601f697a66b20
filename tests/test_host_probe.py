# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The host probe that alone may excuse a real-time test (tests/host_probe.py), and the ledger.

A skip or a rerun needs the host's own evidence: stalls a probe saw beside the test, enough to
account for the loop's trouble. These tests pin the verdicts, the probe process (a stall made
by stopping it is seen, with its length) and the one-line account CI ends with.
"""

import os
import signal
import time
from types import SimpleNamespace

import pytest

from conftest import HOST_SKIP_SHARE_MAX, _Ledger
from host_probe import (
    EXPLAINED_SAMPLES_PER_STALLED_MS,
    RERUN_STALL_MS,
    SLOW_HOST_SPEED,
    HostProbe,
    HostWindow,
    require_speed,
    skip_or_fail,
    slow_host,
)

MS = 1_000_000


def _window(*lates_ms, fifo=True):
    return HostWindow(
        seconds=10.0, fifo=fifo, stalls=[(i, int(ms * MS), 0) for i, ms in enumerate(lates_ms)]
    )


def test_the_stalls_explain_only_as_many_samples_as_their_time_can():
    window = _window(4.0, 6.0)  # 10 ms stalled in all
    assert window.stalled_ms == pytest.approx(10.0) and window.longest_ms == pytest.approx(6.0)
    assert window.explains(10.0 * EXPLAINED_SAMPLES_PER_STALLED_MS)
    assert not window.explains(10.0 * EXPLAINED_SAMPLES_PER_STALLED_MS + 1)
    assert not _window().explains(1)  # a quiet host explains nothing


def test_only_a_stall_beyond_the_measurement_timeout_allows_a_rerun():
    assert not _window(RERUN_STALL_MS).stalled  # exactly the timeout: the loop rides it out
    assert _window(RERUN_STALL_MS + 0.1).stalled


def test_a_probe_without_sched_fifo_excuses_nothing():
    window = _window(50.0, fifo=False)
    assert not window.stalled and not window.explains(1)
    assert 'normal scheduling' in window.summary()


@pytest.fixture
def host_speed(monkeypatch):
    """Set the host's measured speed (host_probe.host_speed) for a test: a function of it."""
    import host_probe

    def set_speed(speed: float) -> None:
        monkeypatch.setattr(host_probe, 'host_speed', lambda: speed)

    set_speed(1.0)
    return set_speed


def test_skip_or_fail_skips_with_both_figures_or_fails_naming_the_quiet_host(host_speed):
    with pytest.raises(pytest.skip.Exception, match=r'^host stalled: 30 late; host probe '):
        skip_or_fail(_window(20.0), '30 late', samples=30)
    with pytest.raises(pytest.fail.Exception) as failed:
        skip_or_fail(_window(1.0), '30 late', samples=30)
    assert str(failed.value) == (
        '30 late; the host does not explain 30 samples of it: host probe (SCHED_FIFO 60, '
        '10.0 s): 1 stalls over 2 ms, 1.0 ms in all, the longest 1.0 ms'
    )
    with pytest.raises(pytest.skip.Exception):
        skip_or_fail(_window(51.0), 'ended early', stall_ms=50.0)
    with pytest.raises(pytest.fail.Exception, match='does not explain a stall of 50 ms'):
        skip_or_fail(_window(49.0), 'ended early', stall_ms=50.0)


def test_a_slow_host_skips_what_a_quiet_one_fails_and_says_its_speed(host_speed):
    """Below SLOW_HOST_SPEED a bad figure skips as 'host slow' and require_speed skips first."""
    host_speed(SLOW_HOST_SPEED)
    assert slow_host() == ''
    require_speed('the loop')  # no skip
    host_speed(SLOW_HOST_SPEED - 0.01)
    assert slow_host().startswith(f'host slow: it runs Python at {SLOW_HOST_SPEED - 0.01:.2f} ')
    with pytest.raises(pytest.skip.Exception, match=r'^host slow: .*: 30 late; host probe '):
        skip_or_fail(_window(1.0), '30 late', samples=30)
    with pytest.raises(pytest.skip.Exception, match=r'^host slow: .*: the loop is judged only'):
        require_speed('the loop')
    # a figure any host speed keeps is excused by the probe's stalls only
    with pytest.raises(pytest.fail.Exception, match='^30 late; the host does not explain'):
        skip_or_fail(_window(1.0), '30 late', samples=30, slow_host_excuses=False)
    with pytest.raises(pytest.skip.Exception, match=r'^host stalled: 30 late'):
        skip_or_fail(_window(20.0), '30 late', samples=30, slow_host_excuses=False)


def test_the_reference_workload_gives_a_speed_near_the_calibration_here():
    """host_speed is REFERENCE_WORKLOAD_S over the workload's best time: a positive number."""
    import host_probe

    host_probe.host_speed.cache_clear()
    speed = host_probe.host_speed()
    assert 0.05 < speed < 20.0, speed  # a workload that ran (not 0 s, not minutes)
    assert host_probe.host_speed() == speed  # once per session


@pytest.mark.slow
def test_the_probe_sees_a_stall_of_its_own_process_with_its_length():
    """The probe's process stopped for 40 ms: a stall that long, seen on that CPU only."""
    probe = HostProbe(cpus=[0])
    probe.start()
    time.sleep(0.2)
    ((_, proc),) = probe.procs
    os.kill(proc.pid, signal.SIGSTOP)
    time.sleep(0.04)
    os.kill(proc.pid, signal.SIGCONT)
    time.sleep(0.2)
    window = probe.stop()
    assert window.fifo, window.summary()  # the tests run where SCHED_FIFO is granted
    assert 35.0 < window.longest_ms < 200.0, window.summary()
    assert {cpu for _, _, cpu in window.stalls} == {0}
    assert window.stalled


def _report(nodeid, outcome, reason=''):
    return SimpleNamespace(
        nodeid=nodeid,
        keywords={'realtime': 1},
        outcome=outcome,
        skipped=outcome == 'skipped',
        longrepr=('file', 1, reason) if reason else None,
    )


def test_the_ledger_counts_reruns_and_host_skips_per_test_and_fails_beyond_the_share(host_speed):
    host_speed(0.6)
    ledger = _Ledger()
    ledger.note(_report('t.py::a', 'rerun'))
    ledger.note(_report('t.py::a', 'passed'))
    ledger.note(_report('t.py::b', 'skipped', 'Skipped: host stalled: x; host probe ...'))
    ledger.note(_report('t.py::c', 'skipped', 'Skipped: this machine refuses SCHED_FIFO'))
    ledger.note(_report('t.py::s', 'skipped', 'Skipped: host slow: it runs Python at 0.60 ...'))
    ledger.note(SimpleNamespace(nodeid='t.py::u', keywords={}, outcome='rerun'))  # not real-time
    assert ledger.line() == (
        'real-time ledger: 4 tests, 1 reruns (a x1), 1 host skips (b); host skips allowed up to '
        f'{HOST_SKIP_SHARE_MAX:.0%}; 1 figures not judged on a slow host (speed 0.60, judged '
        f'from {SLOW_HOST_SPEED:g}: s)'
    )
    assert ledger.too_many_skips() == (1 > HOST_SKIP_SHARE_MAX * 4)  # a slow host's not counted
    for name in 'defgh':
        ledger.note(_report(f't.py::{name}', 'passed'))
    assert not ledger.too_many_skips()  # 1 of 9
