# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""actuator_studies on a Ray cluster as users run one: a head and a separately started worker.

The head (no CPUs, so every task runs on the worker) and the worker are ``ray start --block``
processes whose environment lacks the workspace's PYTHONPATH: the worker imports the project
only from what the driver ships (runtime_env py_modules). Token authentication is on, the token
handed to every process through RAY_AUTH_TOKEN_PATH. Every process binds and advertises
127.0.0.1. The processes are stopped by their process group ids at the end (never
``ray stop``, which would stop other users' Ray processes too).
"""

import json
import os
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from actuator_studies.results import tables_identical
from actuator_studies.sweep import SweepRequest, run_sweep

pytestmark = pytest.mark.ros  # Ray processes

SHORT_S = 5.2
SWEEP_ARGS = [
    '--vary', 'condition.temperature_c=-2:30',
    '--vary', 'encoder.noise_std_rad=0:2e-4',
    '--method', 'lhs', '--samples', '6', '--seed', '5',
    '--batch', '2', '--chunk', '3', '--duration', str(SHORT_S),
]  # fmt: skip


#: ``ray`` with Ray's loopback rewrite off: Ray 2.60 replaces a node or head address of 127.0.0.1
#: by the machine's interface address (``services.resolve_ip_for_localhost``), which a
#: loopback-only cluster must not use. On machines that reach each other by real addresses
#: the plain ``ray`` command is used.
RAY_LOOPBACK = (
    'import sys, ray._private.services as s; s.resolve_ip_for_localhost = lambda host: host; '
    'from ray.scripts.scripts import main; sys.argv[0] = "ray"; main()'
)


#: A driver that waits until the cluster at argv[1] has 2 CPUs and prints the count.
WAIT_FOR_CPUS = (
    'import sys, time, ray; from actuator_studies.distributed import _loopback_only; '
    '_loopback_only(ray); ray.init(address=sys.argv[1], log_to_driver=False, '
    'configure_logging=False); end = time.monotonic() + 60\n'
    "while ray.cluster_resources().get('CPU', 0) < 2 and time.monotonic() < end: time.sleep(0.3)\n"
    "print(float(ray.cluster_resources().get('CPU', 0))); ray.shutdown()"
)


def _free_ports(count: int) -> list[int]:
    """``count`` distinct free TCP ports on 127.0.0.1."""
    socks = [socket.socket() for _ in range(count)]
    for s in socks:
        s.bind(('127.0.0.1', 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


def _node_ports(ports: list[int]) -> list[str]:
    """Explicit ports of one node, so two Ray instances on a machine never collide."""
    names = (
        'node-manager-port',
        'object-manager-port',
        'dashboard-agent-listen-port',
        'dashboard-agent-grpc-port',
        'metrics-export-port',
        'runtime-env-agent-port',
    )
    return [f'--{n}={p}' for n, p in zip(names, ports)]


def _processes_under(temp_dir: str) -> list[int]:
    """Pids whose command line names ``temp_dir`` (the Ray processes of this test only)."""
    pids = []
    for entry in Path('/proc').iterdir():
        if entry.name.isdigit():
            try:
                if temp_dir.encode() in (entry / 'cmdline').read_bytes():
                    pids.append(int(entry.name))
            except OSError:
                continue
    return pids


@pytest.fixture(scope='module')
def cluster(tmp_path_factory):
    """Yield (address, env for a driver); a head and a two-CPU worker without the workspace."""
    ray_cli = [sys.executable, '-c', RAY_LOOPBACK]
    temp_dir = tempfile.mkdtemp(prefix='rt', dir='/tmp')  # sockets need a short path
    token = tmp_path_factory.mktemp('auth') / 'token'
    token.write_text(secrets.token_hex(32))
    auth = {'RAY_AUTH_MODE': 'token', 'RAY_AUTH_TOKEN_PATH': str(token)}
    bare = {k: v for k, v in os.environ.items() if k not in ('PYTHONPATH', 'RAY_ADDRESS')}
    bare.update(auth, RAY_USAGE_STATS_ENABLED='0')
    # The workspace is really missing from the nodes' environment:
    probe = subprocess.run(
        [sys.executable, '-c', 'import actuator_core'], env=bare, capture_output=True, text=True
    )
    assert probe.returncode != 0 and 'ModuleNotFoundError' in probe.stderr
    ports = _free_ports(13)
    address = f'127.0.0.1:{ports[0]}'
    common = ['--block', f'--temp-dir={temp_dir}', '--disable-usage-stats']
    head = subprocess.Popen(
        [*ray_cli, 'start', '--head', f'--port={ports[0]}', '--node-ip-address=127.0.0.1',
         '--num-cpus=0', '--include-dashboard=false', *_node_ports(ports[1:7]), *common],
        env=bare,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )  # fmt: skip
    procs = [head]
    worker_log = open(tmp_path_factory.mktemp('logs') / 'worker.log', 'w')
    try:
        _wait_for(lambda: _connectable(ports[0]), 60, 'the Ray head')
        worker = subprocess.Popen(
            [*ray_cli, 'start', f'--address={address}', '--node-ip-address=127.0.0.1',
             '--num-cpus=2',
             *_node_ports(ports[7:13]), *common],
            env=bare, stdout=worker_log, stderr=subprocess.STDOUT, start_new_session=True,
        )  # fmt: skip
        procs.append(worker)
        _wait_for(
            lambda: _connectable(ports[7]), 120, 'the Ray worker node', Path(worker_log.name)
        )  # its raylet
        driver_env = {**os.environ, **auth}
        # The raylet registers its CPUs with the head after it listens: wait for them.
        cpus = subprocess.run(
            [sys.executable, '-c', WAIT_FOR_CPUS, address], env=driver_env,
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert cpus.stdout.strip() == '2.0', cpus.stderr[-2000:]
        yield address, driver_env, temp_dir
    finally:
        for p in reversed(procs):
            p.send_signal(signal.SIGTERM)
        for p in reversed(procs):
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                pass
            try:
                os.killpg(p.pid, signal.SIGKILL)  # the group this fixture created
            except ProcessLookupError:
                pass
        for pid in _processes_under(temp_dir):  # any straggler of this test's instance
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def _connectable(port: int) -> bool:
    """Tell whether 127.0.0.1:port accepts a connection."""
    try:
        with socket.create_connection(('127.0.0.1', port), timeout=1):
            return True
    except OSError:
        return False


def _wait_for(check, timeout_s: float, what: str, log: Path | None = None) -> None:
    """Poll ``check`` until true; fail naming ``what`` (and its log's tail) after ``timeout_s``."""
    end = time.monotonic() + timeout_s
    while not check():
        if time.monotonic() > end:
            tail = log.read_text()[-3000:] if log is not None and log.exists() else ''
            pytest.fail(f'{what} did not come up within {timeout_s:g} s\n{tail}')
        time.sleep(0.2)


def _cli(env: dict, command: str, *args: str) -> subprocess.CompletedProcess:
    """Run an actuator_studies command as a separate driver process."""
    code = (
        f'import sys; from actuator_studies.cli import {command}; '
        f'sys.exit({command}(sys.argv[1:]))'
    )
    return subprocess.run(
        [sys.executable, '-c', code, *args], env=env, capture_output=True, text=True, timeout=300
    )


def test_a_sweep_on_a_worker_without_the_workspace_equals_the_local_run(cluster, tmp_path):
    address, env, temp_dir = cluster
    proc = _cli(env, 'sweep_main', *SWEEP_ARGS, '--ray', address, '--no-progress',
                '--out', str(tmp_path / 'cluster'))  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert '2 worker(s)' in proc.stdout  # the head has no CPUs: every chunk ran on the worker
    req = SweepRequest(
        vary=['condition.temperature_c=-2:30', 'encoder.noise_std_rad=0:2e-4'],
        method='lhs', samples=6, seed=5, batch=2, chunk=3, duration_s=SHORT_S,
    )  # fmt: skip
    run_sweep(req, tmp_path / 'local', progress=False)
    assert tables_identical(
        pq.read_table(tmp_path / 'cluster' / 'runs.parquet'),
        pq.read_table(tmp_path / 'local' / 'runs.parquet'),
    )
    # Every Ray process of this instance advertises and listens on loopback only.
    listening = subprocess.run(['ss', '-ltnpH'], capture_output=True, text=True).stdout
    ours = {str(p) for p in _processes_under(temp_dir)}
    sockets = [
        line.split()[3]
        for line in listening.splitlines()
        if any(f'pid={p},' in line for p in ours)
    ]
    assert sockets and all('127.0.0.1' in s for s in sockets), sockets
    summary = json.loads((tmp_path / 'cluster' / 'summary.json').read_text())
    assert summary['execution']['executor'] == f'ray {address}'


def test_a_task_error_on_the_cluster_is_shown_in_full_and_not_retried(cluster, tmp_path):
    address, env, _ = cluster
    marker = tmp_path / 'attempts'
    proc = _cli(env, 'sweep_main', *SWEEP_ARGS, '--ray', address, '--no-progress',
                '--out', str(tmp_path / 'x'), '--inject-failure', f'1:raise:{marker}')  # fmt: skip
    assert proc.returncode == 1
    assert 'chunk 1 failed on Ray:' in proc.stderr
    assert 'RuntimeError: injected failure of chunk 1' in proc.stderr
    assert 'ip=127.0.0.1' in proc.stderr  # the worker's address in the remote traceback
    assert marker.read_text().count('\n') == 1


def test_a_design_on_the_cluster_equals_the_local_design(cluster, tmp_path):
    address, env, _ = cluster
    args = ['--trials', '3', '--parallel', '3', '--seed', '2', '--corner', 'depth_m=0,1000',
            '--duration', str(SHORT_S), '--validate-points', '2',
            '--target-radius', '0.999']  # fmt: skip
    proc = _cli(env, 'design_main', *args, '--ray', address, '--out', str(tmp_path / 'cluster'))
    assert proc.returncode == 0, proc.stderr
    local = _cli(env, 'design_main', *args, '--out', str(tmp_path / 'local'))
    assert local.returncode == 0, local.stderr
    a, b = (json.loads((tmp_path / d / 'design.json').read_text()) for d in ('cluster', 'local'))
    assert a['trials'] == b['trials'] and len(a['trials']) == 3
    assert a['validation'] == b['validation'] and a['in_sample'] == b['in_sample']
