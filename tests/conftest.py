# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Fixtures shared by every test of the project (tooling in tests/ros_helpers.py).

    ros_domain_id   a ROS domain id reserved for this test alone (ros_helpers.reserve_domain)
    ros_env         environment dict for subprocesses: that domain, localhost-only discovery,
                    per-test ROS_LOG_DIR, unbuffered output, plus the project environment
    rclpy_context   rclpy initialised in this pytest process on the same isolated domain
                    (os.environ patched for the test); yields the rclpy Context to pass as
                    ``context=`` to Node and executors
    ros_process     factory: ros_process(pkg, exe, args) -> started RosProcess, logs in
                    tmp_path, stopped (SIGINT, SIGTERM, SIGKILL) when the test ends
    isolated        bring-up code run in this process: os.environ set to ros_env, cwd a
                    scratch folder (returned)
    run_bag         (path, SyntheticRun) of one synthetic 1 s run bag with the five system
                    topics in 64 KiB chunks (bag_helpers), written once per session; read only

Run the tests through ``make test`` (or ``scripts/test.sh``), or after
``source scripts/env.sh``.
"""

from __future__ import annotations

import functools
import json
import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import host_probe  # noqa: E402
import ros_helpers  # noqa: E402
from host_probe import SLOW_HOST_SPEED, HostProbe, HostWindow  # noqa: E402


def _require_project_environment():
    problem = ros_helpers.check_project_environment()
    if problem:
        pytest.fail(
            f'the project environment is not active ({problem}). Run the tests with '
            f'`make test` or `scripts/test.sh`, or `source scripts/env.sh` first.',
            pytrace=False,
        )


def pytest_report_header(config):
    return (
        f'ROS: {os.environ.get("ACTUATOR_ROS_MODE")} mode, RMW '
        f'{os.environ.get("RMW_IMPLEMENTATION")}, '
        f'workspace {os.environ.get("ACTUATOR_WS")}'
    )


@pytest.fixture
def ros_domain_id():
    _require_project_environment()
    with ros_helpers.reserve_domain() as domain_id:
        yield domain_id


@pytest.fixture
def ros_env(ros_domain_id, tmp_path):
    log_dir = tmp_path / 'ros_log'
    log_dir.mkdir(exist_ok=True)
    return ros_helpers.isolated_ros_env(ros_domain_id, log_dir=log_dir)


@pytest.fixture
def rclpy_context(ros_env, monkeypatch):
    import rclpy
    from rclpy.context import Context

    for name in ros_helpers.ISOLATION_UNSET:
        monkeypatch.delenv(name, raising=False)
    for name in (*ros_helpers.ISOLATION_SET, 'RMW_IMPLEMENTATION', 'ROS_LOG_DIR'):
        monkeypatch.setenv(name, ros_env[name])
    context = Context()
    rclpy.init(context=context, domain_id=int(ros_env['ROS_DOMAIN_ID']))
    try:
        yield context
    finally:
        context.try_shutdown()


@pytest.fixture
def ros_process(ros_env, tmp_path):
    started = []

    def start(package, executable, args=(), env=None, **kwargs):
        proc = ros_helpers.RosProcess.installed(
            package,
            executable,
            args,
            env=ros_env if env is None else env,
            log_dir=tmp_path / 'processes',
            **kwargs,
        )
        started.append(proc)
        return proc

    yield start
    for proc in started:
        proc.stop()


@pytest.fixture
def isolated(ros_env, monkeypatch, tmp_path):
    for key, value in ros_env.items():
        monkeypatch.setenv(key, value)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.fixture(scope='session')
def run_bag(tmp_path_factory):
    from bag_helpers import synthetic_run, write_run_bag

    run = synthetic_run(duration_s=1.0)
    path = write_run_bag(tmp_path_factory.mktemp('run_bag') / 'case', run, chunk_size=64 * 1024)
    return path, run


@pytest.fixture(autouse=True)
def _no_orphan_processes():
    """Whatever RosProcess a test started and left running is stopped when the test ends.

    Processes that were already running when the test began (started by module- or
    session-scoped fixtures) are left to their own fixtures; the atexit hook of
    ros_helpers stops anything still alive when pytest exits.
    """
    before = set(ros_helpers.live_processes())
    yield
    for proc in ros_helpers.live_processes():
        if proc not in before:
            proc.stop(sigint_timeout=3.0, sigterm_timeout=2.0)


#: More runs a failed real-time test gets, each only when the host probe saw the host stall in the
#: failed attempt (host_probe.HostWindow.stalled): a failure on a quiet host is final.
#: ACTUATOR_REALTIME_RERUNS=0 shows each failure.
REALTIME_RERUNS = int(os.environ.get('ACTUATOR_REALTIME_RERUNS', '2'))
#: Share of the real-time tests that may end as host skips before the run fails: beyond it the
#: machine measured itself, not the loop, and the run judged too little.
HOST_SKIP_SHARE_MAX = 0.25
#: Where the session's real-time ledger (reruns, host skips) is written for scripts/test.sh.
LEDGER_PATH = os.environ.get('ACTUATOR_TEST_LEDGER', '')

ROS_FIXTURES = {'ros_domain_id', 'ros_env', 'rclpy_context', 'ros_process'}


def _host_stalled(item, _error=None) -> bool:
    """Rerun condition of a real-time test: its failed attempt's probe saw the host stall."""
    window = getattr(item, 'host_window', None)
    return window is not None and window.stalled


def pytest_collection_modifyitems(config, items):
    """Mark each test.

    ros when it uses a ROS fixture (or says so), realtime implies ros, else unit.
    """
    for item in items:
        marks = {m.name for m in item.iter_markers()}
        if 'realtime' in marks:
            # A real-time run shares 2 cores with everything else on the machine, and a host
            # stall of tens of milliseconds can cost one run its tracking: a failed attempt gets
            # another run only when the host probe saw such a stall in it (pytest-rerunfailures'
            # condition is asked after each failed attempt).
            item.add_marker(
                pytest.mark.flaky(
                    reruns=REALTIME_RERUNS, condition=functools.partial(_host_stalled, item)
                )
            )
            item.fixturenames.append('host_window')
        if 'realtime' in marks or ROS_FIXTURES & set(getattr(item, 'fixturenames', ())):
            item.add_marker(pytest.mark.ros)
        elif 'ros' not in marks:
            item.add_marker(pytest.mark.unit)


@pytest.fixture
def host_window(request):
    """Run the host probe over this real-time test; yield the window a test may judge with.

    A test reads it through ``host_probe.skip_or_fail``; at teardown the probe's figures go to
    ``request.node.host_window``, which the rerun condition reads.
    """
    probe = HostProbe()
    probe.start()
    window = HostWindow()
    request.node.host_window = window
    live = _LiveWindow(probe, window)
    yield live
    live.settle()


class _LiveWindow(HostWindow):
    """A HostWindow that reads the probe when the test asks (the probe keeps running)."""

    def __init__(self, probe: HostProbe, target: HostWindow):
        super().__init__()
        self._probe, self._target = probe, target

    def settle(self) -> None:
        """Stop the probe once; copy what it saw here and into the item's window."""
        if self._probe is not None:
            seen = self._probe.stop()
            self._probe = None
            for target in (self, self._target):
                target.seconds, target.fifo = seen.seconds, seen.fifo
                target.stalls, target.problem = seen.stalls, seen.problem


class _Ledger:
    """Reruns and host skips of the session's real-time tests, for the last line of CI."""

    def __init__(self):
        self.realtime: set[str] = set()
        self.reruns: dict[str, int] = {}
        self.host_skips: dict[str, str] = {}
        self.slow_skips: dict[str, str] = {}

    def note(self, report) -> None:
        """Count one report of a real-time test."""
        if 'realtime' not in report.keywords:
            return
        self.realtime.add(report.nodeid)
        if report.outcome == 'rerun':
            self.reruns[report.nodeid] = self.reruns.get(report.nodeid, 0) + 1
        elif report.skipped and 'host stalled:' in str(report.longrepr):
            self.host_skips[report.nodeid] = str(report.longrepr[-1])
        elif report.skipped and 'host slow:' in str(report.longrepr):
            self.slow_skips[report.nodeid] = str(report.longrepr[-1])

    def line(self) -> str:
        """Return the one-line account (reruns and host skips per test, the share)."""

        def short(nodeid):
            return nodeid.split('::')[-1]

        reruns = ', '.join(f'{short(k)} x{v}' for k, v in sorted(self.reruns.items()))
        skips = ', '.join(short(k) for k in sorted(self.host_skips))
        slow = ', '.join(short(k) for k in sorted(self.slow_skips))
        line = (
            f'real-time ledger: {len(self.realtime)} tests, {sum(self.reruns.values())} reruns '
            f'({reruns or "none"}), {len(self.host_skips)} host skips ({skips or "none"}); '
            f'host skips allowed up to {HOST_SKIP_SHARE_MAX:.0%}'
        )
        if self.slow_skips:  # a precondition of the host, like SCHED_FIFO: said, not counted
            line += (
                f'; {len(self.slow_skips)} figures not judged on a slow host (speed '
                f'{host_probe.host_speed():.2f}, judged from {SLOW_HOST_SPEED:g}: {slow})'
            )
        return line

    def too_many_skips(self) -> bool:
        """Return whether host skips exceed HOST_SKIP_SHARE_MAX of the real-time tests run."""
        return len(self.host_skips) > HOST_SKIP_SHARE_MAX * max(len(self.realtime), 1)


LEDGER = _Ledger()


def pytest_runtest_logreport(report):
    LEDGER.note(report)


def pytest_sessionfinish(session, exitstatus):
    if not LEDGER.realtime:
        return
    if LEDGER_PATH:
        Path(LEDGER_PATH).write_text(
            json.dumps(
                {
                    'line': LEDGER.line(),
                    'too_many_host_skips': LEDGER.too_many_skips(),
                    'reruns': LEDGER.reruns,
                    'host_skips': LEDGER.host_skips,
                }
            )
        )
    if LEDGER.too_many_skips() and session.exitstatus == 0:
        session.exitstatus = 1


def pytest_terminal_summary(terminalreporter):
    if LEDGER.realtime:
        terminalreporter.write_line(LEDGER.line())
