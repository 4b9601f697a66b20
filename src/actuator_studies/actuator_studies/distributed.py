# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Where a study's chunks run: in this process, or as Ray tasks on a local instance or a cluster.

Both executors yield (chunk, columns) as chunks finish, so the caller writes each chunk at
once (and a rerun with --resume skips it). A chunk is one task; a chunk's result does not
depend on where it ran (same code, same per-run seeds), so a Ray run equals a local run row
for row.

Shipping the code: every Ray job gets a ``runtime_env`` whose ``py_modules`` are the project's
ROS-free packages (``SHIPPED_PACKAGES``, taken from this process's imports), so a worker node
needs only Python with Ray and the pinned dependencies, not this workspace on its path.

Failures: an exception raised by a chunk is deterministic (same inputs, same code) and is not
retried: the study ends at once with that error in full (type, message, the remote traceback).
A chunk whose worker process or node is lost is run again, up to ``MAX_RETRIES`` more times
(``max_retries`` with ``retry_exceptions`` off). A failed chunk is never silently missing
(``results.join_chunks`` refuses to join an incomplete study).

Backpressure: at most ``IN_FLIGHT_PER_CPU`` tasks per cluster CPU are submitted at a time,
and ``ray.wait`` runs over those only, so the driver's work per finished chunk does not grow
with the study. Every task declares the memory it needs (``task_memory_bytes``).

``--ray local:N`` starts a private local instance with N CPUs (``address='local'``, so it
never attaches to someone else's cluster), bound to 127.0.0.1; ``--ray HOST:PORT`` connects to
a running cluster, checked with a short TCP connect first so an unreachable address fails in
seconds.
"""

from __future__ import annotations

import importlib
import os
import re
import socket
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator

from actuator_studies.runner import SweepSpec, run_chunk, task_memory_bytes
from actuator_studies.space import StudyInputError

#: Further attempts of a chunk whose worker was lost (exceptions are never retried).
MAX_RETRIES = 3
#: Seconds to wait for a TCP connection to a Ray address before calling it unreachable.
CONNECT_TIMEOUT_S = 3.0
#: Object store of a local instance [bytes]:
#: chunks are small, keep the shared machine's memory free.
LOCAL_OBJECT_STORE_BYTES = 200 * 1024 * 1024
#: Tasks in flight per cluster CPU (one running, one queued so a CPU never waits on the driver).
IN_FLIGHT_PER_CPU = 2
#: The project's packages a task imports (all ROS-free), shipped to workers as py_modules.
SHIPPED_PACKAGES = (
    'actuator_core',
    'actuator_plant',
    'actuator_eso',
    'actuator_controller',
    'actuator_sim',
    'actuator_studies',
)
#: Loopback address every Ray process of a local instance binds and advertises.
LOOPBACK = '127.0.0.1'


@dataclass(frozen=True)
class InjectedFailure:
    """Test hook.

    The first attempt of ``chunk`` fails, by an exception or by killing its process.
    """

    chunk: int
    marker: str  # file created by the failing attempt; later attempts find it and run
    mode: str = 'raise'  # raise (every attempt, logged to marker) | exit (first attempt dies)


def attempt_chunk(spec: SweepSpec, chunk: int, inject: InjectedFailure | None = None) -> dict:
    """Run one chunk (an injected exit strikes the first attempt only)."""
    if inject is not None and inject.chunk == chunk:
        if inject.mode == 'raise':
            with open(inject.marker, 'a') as attempts:  # one line per attempt
                attempts.write(f'chunk {chunk} raised in process {os.getpid()}\n')
            raise RuntimeError(f'injected failure of chunk {chunk}')
        if not os.path.exists(inject.marker):
            Path(inject.marker).write_text(
                f'chunk {chunk} lost its process {os.getpid()} on purpose\n'
            )
            os._exit(17)
    return run_chunk(spec, chunk)


class ChunkFailed(RuntimeError):
    """A chunk raised, or lost its worker on every attempt; the message holds the cause in full."""


def run_local(
    spec: SweepSpec, chunks: Iterable[int], inject: InjectedFailure | None = None
) -> Iterator[tuple]:
    """Run chunks one after another in this process; yield (chunk, columns).

    A chunk that raises ends the study with ChunkFailed and its traceback (no retry: the same
    inputs fail the same way).
    """
    for chunk in chunks:
        try:
            columns = attempt_chunk(spec, chunk, inject)
        except Exception as exc:  # noqa: BLE001 - reported in full, never retried
            raise ChunkFailed(
                f'chunk {chunk} failed:\n{"".join(traceback.format_exception(exc)).rstrip()}'
            ) from exc
        yield chunk, columns


def parse_ray_target(text: str) -> tuple[str, int | None]:
    """'local:N' -> ('local', N); an address -> (address, None); StudyInputError when malformed."""
    if text.startswith('local'):
        _, _, count = text.partition(':')
        if not count.isdigit() or int(count) < 1:
            raise StudyInputError(f'--ray {text!r}: expected local:N with N >= 1 workers')
        return 'local', int(count)
    host_port = text.split('://', 1)[-1]
    host, _, port = host_port.rpartition(':')
    if not host or not port.isdigit():
        raise StudyInputError(
            f'--ray {text!r}: expected local:N or HOST:PORT of a running Ray cluster'
        )
    return text, None


def check_reachable(address: str) -> None:
    """StudyInputError unless a TCP connection to the address opens within CONNECT_TIMEOUT_S."""
    host, _, port = address.split('://', 1)[-1].rpartition(':')
    try:
        with socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT_S):
            pass
    except OSError as exc:
        raise StudyInputError(
            f'Ray address {address} is unreachable ({exc.strerror or exc})'
        ) from None


def shipped_modules() -> list[str]:
    """Directories of SHIPPED_PACKAGES as this process imports them (symlinks resolved)."""
    return [str(Path(_module_file(name)).resolve().parent) for name in SHIPPED_PACKAGES]


def _module_file(name: str) -> str:
    """Return the file a package of the project is imported from (none is a namespace one)."""
    path = importlib.import_module(name).__file__
    assert path is not None, f'{name} is a namespace package'
    return path


def runtime_env() -> dict:
    """Runtime environment of every study job: the project's packages as py_modules."""
    return {'py_modules': shipped_modules(), 'excludes': ['__pycache__', '*.pyc']}


def start_ray(target: str):
    """Start (local:N) or join (address) Ray, shipping the project's packages.

    Return the ray module. StudyInputError when it cannot.
    """
    address, cpus = parse_ray_target(target)
    if cpus is None:
        check_reachable(address)
    import ray

    try:
        if cpus is not None:
            _loopback_only(ray)
            ray.init(
                address='local',
                num_cpus=cpus,
                include_dashboard=False,
                log_to_driver=False,
                object_store_memory=LOCAL_OBJECT_STORE_BYTES,
                configure_logging=False,
                _node_ip_address=LOOPBACK,
                runtime_env=runtime_env(),
            )
        else:
            host = address.split('://', 1)[-1].rpartition(':')[0]
            if host in (LOOPBACK, 'localhost'):
                _loopback_only(ray)  # a head on loopback: this driver stays on loopback too
            ray.init(
                address=address,
                log_to_driver=False,
                configure_logging=False,
                runtime_env=runtime_env(),
            )
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise StudyInputError(
            f'cannot start or join Ray at {target}: {str(exc).splitlines()[0]}'
        ) from None
    return ray


def _loopback_only(ray) -> None:
    """Make a local instance bind and advertise 127.0.0.1 (Ray 2.60 swaps it otherwise).

    Ray replaces a node address of 127.0.0.1 by the machine's interface address unless its
    single-machine mode is on (``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``); the variable is read
    at import, so it is set for the instance's processes and in the imported constants.
    """
    import ray._private.ray_constants as ray_constants

    os.environ[ray_constants.ENABLE_RAY_CLUSTERS_ENV_VAR] = '0'
    ray_constants.ENABLE_RAY_CLUSTER = False


def ray_workers(ray) -> int:
    """CPUs of the Ray cluster (one single-CPU task per CPU at a time)."""
    return int(ray.cluster_resources().get('CPU', 0))


def failure_text(exc: BaseException) -> str:
    """Return what a failed Ray task says in full: the remote traceback, or the lost worker."""
    import ray.exceptions as rex

    if isinstance(exc, rex.RayTaskError):
        text = str(exc)  # the task's own exception, with its traceback on the worker
    else:
        text = f'{type(exc).__name__}: {exc}'
    return re.sub(r'\x1b\[[0-9;]*m', '', text).rstrip()


def stream_tasks(
    ray,
    remote_fn,
    calls: Iterable[tuple],
    label: Callable[[tuple], str] = str,
    in_flight: int | None = None,
    memory_bytes: int | None = None,
) -> Iterator[tuple]:
    """Run ``remote_fn(*args)`` for every args tuple as Ray tasks; yield (args, result).

    At most ``in_flight`` tasks (default IN_FLIGHT_PER_CPU per cluster CPU) are submitted at a
    time, and ``ray.wait`` looks at those only. A task that raises, or loses its worker more
    than MAX_RETRIES times, ends the stream with ChunkFailed (the other tasks are cancelled).
    """
    limit = in_flight or max(1, IN_FLIGHT_PER_CPU * ray_workers(ray))
    options = {'num_cpus': 1, 'max_retries': MAX_RETRIES, 'retry_exceptions': False}
    if memory_bytes:
        options['memory'] = int(memory_bytes)
    task = remote_fn.options(**options)
    todo = iter(calls)
    running: dict = {}

    def submit() -> None:
        for args in todo:
            running[task.remote(*args)] = args
            if len(running) >= limit:
                return

    submit()
    while running:
        done, _ = ray.wait(list(running), num_returns=1)
        args = running.pop(done[0])
        try:
            result = ray.get(done[0])
        except Exception as exc:  # noqa: BLE001 - Ray wraps the task's own error
            for ref in running:
                ray.cancel(ref, force=True)
            raise ChunkFailed(f'{label(args)} failed on Ray:\n{failure_text(exc)}') from exc
        submit()
        yield args, result


def run_ray(
    ray, spec: SweepSpec, chunks: Iterable[int], inject: InjectedFailure | None = None
) -> Iterator[tuple]:
    """Run chunks as Ray tasks with backpressure; yield (chunk, columns) as each finishes."""
    spec_ref = ray.put(spec)
    remote = ray.remote(attempt_chunk)
    for args, columns in stream_tasks(
        ray,
        remote,
        ((spec_ref, chunk, inject) for chunk in chunks),
        label=lambda args: f'chunk {args[1]}',
        memory_bytes=task_memory_bytes(spec),
    ):
        yield args[1], columns
