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

import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ros_helpers  # noqa: E402


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


#: More runs a failed real-time test gets. One was not enough: the CI runs of two stops in a row
#: failed real-time tests in both of their runs on a shared 2-core VM (stops 27 and 28).
#: ACTUATOR_REALTIME_RERUNS=0 shows each failure (to measure how often a run fails).
REALTIME_RERUNS = int(os.environ.get('ACTUATOR_REALTIME_RERUNS', '2'))

ROS_FIXTURES = {'ros_domain_id', 'ros_env', 'rclpy_context', 'ros_process'}


def pytest_collection_modifyitems(config, items):
    """Mark each test.

    ros when it uses a ROS fixture (or says so), realtime implies ros, else unit.
    """
    for item in items:
        marks = {m.name for m in item.iter_markers()}
        if 'realtime' in marks:
            # Real-time runs share 2 cores with everything else on the machine; a stall of tens of
            # milliseconds (no PREEMPT_RT, a hypervisor) can cost one run its tracking. Such a test
            # gets REALTIME_RERUNS more runs (pytest-rerunfailures, pinned); failing each fails.
            item.add_marker(pytest.mark.flaky(reruns=REALTIME_RERUNS))
        if 'realtime' in marks or ROS_FIXTURES & set(getattr(item, 'fixturenames', ())):
            item.add_marker(pytest.mark.ros)
        elif 'ros' not in marks:
            item.add_marker(pytest.mark.unit)
