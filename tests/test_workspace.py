# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The workspace itself.

It builds from a clean clone, every executable is where `ros2 run` looks, and the shared test
tooling (isolated domains, RosProcess) does what it promises.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import re
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

import message_fill
import ros_helpers

WS = ros_helpers.WORKSPACE
HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
COLCON = [
    sys.executable,
    '-c',
    'import sys; sys.argv[0] = "colcon"; from colcon_core.command import main; sys.exit(main())',
]


def _source_packages(src: Path):
    """{name: build_type} of every package.xml under src (not below a COLCON_IGNORE)."""
    packages = {}
    for xml in sorted(src.rglob('package.xml')):
        if any(
            (parent / 'COLCON_IGNORE').exists()
            for parent in xml.parents
            if src in parent.parents or parent == src
        ):
            continue
        root = ET.parse(xml).getroot()
        build_type = root.findtext('export/build_type') or 'catkin'
        packages[root.findtext('name')] = build_type
    return packages


def _is_alive(pid: int) -> bool:
    """Return True for a running process, False for a gone or zombie one."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            state = f.read().rsplit(')', 1)[1].split()[0]
    except FileNotFoundError:
        return False
    return state not in ('Z', 'X')


# -- the workspace ------------------------------------------------------------------------------
@pytest.mark.ros
def test_workspace_builds_from_a_clean_clone(tmp_path):
    """`git clone` of HEAD, then `colcon build` of its src/ with the same tools.

    The result works: messages import and packages resolve to the clone's install/.
    """
    if (
        subprocess.run(['git', '-C', str(WS), 'rev-parse', 'HEAD'], capture_output=True).returncode
        != 0
    ):
        pytest.skip('the workspace is not a git checkout, so there is no HEAD to clone')
    clone = tmp_path / 'clone'
    subprocess.run(['git', 'clone', '--quiet', '--no-local', str(WS), str(clone)], check=True)
    env = ros_helpers.env_without_workspace(os.environ)
    expected = _source_packages(clone / 'src')
    assert 'actuator_msgs' in expected

    started = time.monotonic()
    build = subprocess.run(
        [
            *COLCON,
            '--log-base',
            'log',
            'build',
            '--base-paths',
            'src',
            '--symlink-install',
            '--cmake-args',
            '-DBUILD_TESTING=OFF',
        ],
        cwd=clone,
        env=env,
        capture_output=True,
        text=True,
        timeout=1200,
        stdin=subprocess.DEVNULL,
    )
    elapsed = time.monotonic() - started
    assert build.returncode == 0, (
        f'colcon build failed in the clone:\n{build.stdout[-6000:]}\n{build.stderr[-6000:]}'
    )
    summary = re.search(r'Summary: (\d+) packages? finished', build.stdout)
    assert summary and int(summary.group(1)) == len(expected), build.stdout[-3000:]
    print(f'clean-clone colcon build of {len(expected)} packages: {elapsed:.1f} s')

    probe = (
        'import json, actuator_msgs.msg\n'
        'from ament_index_python.packages import get_package_prefix\n'
        f'names = {sorted(expected)!r}\n'
        'print(json.dumps({n: get_package_prefix(n) for n in names}))\n'
    )
    run = subprocess.run(
        ['bash', '-c', 'source install/setup.bash && exec "$0" -c "$1"', sys.executable, probe],
        cwd=clone,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    prefixes = json.loads(run.stdout.strip().splitlines()[-1])
    for name, prefix in prefixes.items():
        assert Path(prefix) == clone / 'install' / name, (name, prefix)


def test_every_console_script_is_where_ros2_run_looks():
    """Every console_scripts entry point is an executable lib/<pkg>/<exe>.

    For every ament_python package in src/, each console_scripts entry point of its installed
    metadata is the executable lib/<pkg>/<exe> under the ament-index prefix.
    """
    packages = _source_packages(WS / 'src')
    python_packages = sorted(n for n, bt in packages.items() if bt == 'ament_python')
    assert python_packages, 'no ament_python package in src/'
    checked = 0
    for package in python_packages:
        from ament_index_python.packages import get_package_prefix, get_package_share_directory

        prefix = Path(get_package_prefix(package))
        assert prefix == WS / 'install' / package, (
            f'{package} resolves to {prefix}, not this workspace'
        )
        assert (Path(get_package_share_directory(package)) / 'package.xml').is_file()
        scripts = [
            ep
            for ep in importlib.metadata.distribution(package).entry_points
            if ep.group == 'console_scripts'
        ]
        for ep in scripts:
            path = Path(ros_helpers.executable_path(package, ep.name))
            assert path == prefix / 'lib' / package / ep.name
            assert os.access(path, os.X_OK), f'{path} is not executable'
            shebang = path.read_text().splitlines()[0]
            interpreter = Path(shebang[2:].strip().split()[0])
            # The venv's interpreter, which sees the venv's packages (rosbags, mcap, ...).
            assert shebang.startswith('#!') and interpreter.parent == Path(sys.prefix) / 'bin', (
                shebang
            )
            assert f"'{ep.name}'" in path.read_text() or ep.value.split(':')[0] in path.read_text()
            checked += 1
    assert checked > 0, 'no console_scripts declared by any package'


def test_every_package_in_src_is_installed():
    from ament_index_python.packages import get_packages_with_prefixes

    installed = get_packages_with_prefixes()
    for package in _source_packages(WS / 'src'):
        assert package in installed, f'{package} is in src/ but not in the ament index'
        assert Path(installed[package]) == WS / 'install' / package


# -- the test tooling ------------------------------------------------------------------------
def test_isolated_domains_do_not_see_each_other(rclpy_context, ros_env, tmp_path):
    """A node in this process hears a publisher on its own domain, never one on another.

    A node in this process hears a publisher process on its own domain and never one on another
    test's domain, though both publish the same topic and type on this host.
    """
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from actuator_msgs.msg import CurrentCommand

    assert ros_env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    assert os.environ['ROS_DOMAIN_ID'] == ros_env['ROS_DOMAIN_ID']
    script = HERE / 'msg_exchange.py'
    mine = message_fill.message_leaves(message_fill.fill_message(CurrentCommand(), 1))
    theirs = message_fill.message_leaves(message_fill.fill_message(CurrentCommand(), 2))
    assert mine != theirs

    with ros_helpers.reserve_domain(exclude=[int(ros_env['ROS_DOMAIN_ID'])]) as other:
        assert other != int(ros_env['ROS_DOMAIN_ID'])
        other_env = ros_helpers.isolated_ros_env(other, log_dir=tmp_path / 'other_log')
        args = ['pub', '--types', 'CurrentCommand']
        with (
            ros_helpers.RosProcess.python(
                script, [*args, '--seed', '1'], env=ros_env, log_dir=tmp_path, name='same_domain'
            ) as same,
            ros_helpers.RosProcess.python(
                script,
                [*args, '--seed', '2'],
                env=other_env,
                log_dir=tmp_path,
                name='other_domain',
            ) as foreign,
        ):
            same.wait_for_output('^READY$', timeout=30)
            foreign.wait_for_output('^READY$', timeout=30)

            probe = ros_helpers.TestNode(rclpy_context, 'isolation_probe')
            got = []
            qos = QoSProfile(
                depth=1,
                reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.TRANSIENT_LOCAL,
            )
            probe.node.create_subscription(
                CurrentCommand,
                'exchange/CurrentCommand',
                lambda m: got.append(message_fill.message_leaves(m)),
                qos,
            )
            try:
                probe.wait_for(lambda: got, 20.0, 'the publisher on the same domain')
                probe.spin(2.0)  # time enough for the other domain to show up
            finally:
                probe.close()
    assert got, 'nothing received from the publisher on the same domain'
    assert all(m == mine for m in got), got
    assert theirs not in got


@pytest.mark.ros
def test_ros_process_escalates_and_leaves_no_orphans(tmp_path):
    """SIGINT ignored -> SIGTERM; a grandchild that ignores both still does not survive."""
    stubborn = (
        'import signal, subprocess, sys, time\n'
        'child = subprocess.Popen([sys.executable, "-c", "import signal, time; '
        'signal.signal(signal.SIGINT, signal.SIG_IGN); signal.signal(signal.SIGTERM, '
        'signal.SIG_IGN); '
        'time.sleep(300)"])\n'
        'signal.signal(signal.SIGINT, signal.SIG_IGN)\n'
        'print("child", child.pid, flush=True)\n'
        'time.sleep(300)\n'
    )
    proc = ros_helpers.RosProcess(
        [sys.executable, '-c', stubborn], log_dir=tmp_path, name='stubborn'
    )
    with proc:
        child_pid = int(proc.wait_for_output(r'^child (\d+)$', timeout=20).group(1))
        assert _is_alive(child_pid)
        started = time.monotonic()
        rc = proc.stop(sigint_timeout=1.0, sigterm_timeout=5.0)
    assert proc.stopped_by == 'SIGTERM'
    assert rc == -15
    assert time.monotonic() - started < 8
    assert ros_helpers.wait_until(lambda: not _is_alive(child_pid), timeout=5), (
        'grandchild survived'
    )

    quick = ros_helpers.RosProcess(
        [sys.executable, '-c', 'print("hello"); raise SystemExit(3)'],
        log_dir=tmp_path,
        name='quick',
    )
    assert quick.wait(timeout=30) == 3
    assert quick.stopped_by == 'exit' and quick.stdout.strip() == 'hello'
    assert (tmp_path / 'quick.stdout').read_text().strip() == 'hello'


def _ignores_sigint(pid: int) -> bool:
    """Return whether the process ignores SIGINT (its SigIgn mask in /proc)."""
    with open(f'/proc/{pid}/status') as f:
        mask = next(line.split()[1] for line in f if line.startswith('SigIgn:'))
    return bool(int(mask, 16) & (1 << (signal.SIGINT - 1)))


@pytest.mark.ros
def test_ros_process_stops_with_sigint_even_where_its_starter_ignores_sigint(tmp_path):
    """A starter ignoring SIGINT (a background job of a non-interactive shell) passes it on.

    A plain Popen's child ignores SIGINT then; a RosProcess's does not, and its SIGINT stops it
    (``ros2 launch`` would otherwise only end by SIGTERM, orphaning its nodes).
    """
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        plain = subprocess.Popen(['sleep', '60'])
        proc = ros_helpers.RosProcess(['sleep', '60'], log_dir=tmp_path, name='sleeper')
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        assert _ignores_sigint(plain.pid)  # what the fix is for
    finally:
        plain.kill()
        plain.wait()
    with proc:
        assert not _ignores_sigint(proc.pid)
        assert proc.stop(sigint_timeout=5.0) == -signal.SIGINT
    assert proc.stopped_by == 'SIGINT'


@pytest.mark.slow
def test_ros_process_asks_a_hung_process_for_its_stacks_before_sigkill(tmp_path):
    """A node that ignores SIGINT and SIGTERM leaves every thread's stack in its stderr."""
    hung = (
        'import faulthandler, signal, time\n'
        'signal.signal(signal.SIGINT, signal.SIG_IGN)\n'
        'signal.signal(signal.SIGTERM, signal.SIG_IGN)\n'
        'faulthandler.register(signal.SIGUSR1, all_threads=True)\n'
        'def stuck_in_shutdown():\n'
        '    time.sleep(300)\n'
        'print("ready", flush=True)\n'
        'stuck_in_shutdown()\n'
    )
    proc = ros_helpers.RosProcess([sys.executable, '-c', hung], log_dir=tmp_path, name='hung')
    with proc:
        proc.wait_for_output(r'^ready$', timeout=20)
        rc = proc.stop(sigint_timeout=0.5, sigterm_timeout=0.5)
    assert rc == -9 and proc.stopped_by == 'SIGKILL'
    stderr = (tmp_path / 'hung.stderr').read_text()
    assert 'most recent call first' in stderr and 'stuck_in_shutdown' in stderr, stderr


def test_executable_path_reports_missing_executables():
    from ament_index_python.packages import PackageNotFoundError

    with pytest.raises(FileNotFoundError):
        ros_helpers.executable_path('actuator_msgs', 'no_such_executable')
    with pytest.raises(PackageNotFoundError):
        ros_helpers.executable_path('no_such_package_xyz', 'x')


@pytest.mark.ros
def test_readme_commands_work_from_a_shell_that_sourced_env_sh(tmp_path):
    """Run set-up, build, ros2run and make test from a sourced shell: the venv survives."""
    python = ROOT / '.venv' / 'bin' / 'python'
    before = python.resolve()
    script = (
        'set -e; source scripts/env.sh; '
        'bash scripts/setup.sh; make setup; make build; '
        'scripts/ros2run actuator_sim offline_sim run --duration 5.5 --no-traces '
        f'--json {tmp_path / "r.json"}; '
        "make test ARGS='-m unit -k test_gate_honours -p no:cacheprovider -q'"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith('PYTEST')}
    proc = subprocess.run(
        ['bash', '-c', script], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert 'recreating it' not in out and python.resolve() == before  # the working venv was kept
    assert 'up to date' in out and '1 passed' in out
    assert json.loads((tmp_path / 'r.json').read_text())['runs'][0]['metrics']['samples'] == 5500
