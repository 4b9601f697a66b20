# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Where a study's chunks run: in this process, or as Ray tasks on a local instance or a cluster.

Both executors yield (chunk, columns) as chunks finish, so the caller writes each chunk at
once (and a rerun with --resume skips it). A chunk is one task: the vectorised batch is the
unit of work, and a chunk's result does not depend on where it ran (same code, same
per-run seeds), so a Ray run equals a local run row for row.

Failures: a chunk whose attempt raises, or whose worker process dies, is run again, up to
``MAX_RETRIES`` more times (Ray: ``max_retries`` with ``retry_exceptions``; locally: a
loop). A chunk that still fails is reported and the study ends with an error: a chunk is
never silently missing (``results.join_chunks`` refuses to join an incomplete study).

``--ray local:N`` starts a private local instance with N CPUs (``address='local'``, so it
never attaches to someone else's cluster); ``--ray HOST:PORT`` (or ``ray://HOST:PORT``)
connects to a running cluster, checked with a short TCP connect first so an unreachable
address fails in seconds. The cluster's workers must have this workspace installed (the
local instance inherits this process's environment).
"""

from __future__ import annotations

import os
import socket
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator

from actuator_studies.runner import SweepSpec, run_chunk
from actuator_studies.space import StudyInputError

#: Further attempts after a chunk's first one fails (exception or lost worker).
MAX_RETRIES = 3
#: Seconds to wait for a TCP connection to a Ray address before calling it unreachable.
CONNECT_TIMEOUT_S = 3.0
#: Object store of a local instance [bytes]:
#: chunks are small, keep the shared machine's memory free.
LOCAL_OBJECT_STORE_BYTES = 200 * 1024 * 1024


@dataclass(frozen=True)
class InjectedFailure:
    """Test hook.

    The first attempt of ``chunk`` fails, by an exception or by killing its process.
    """

    chunk: int
    marker: str  # file created by the failing attempt; later attempts find it and run
    mode: str = 'raise'  # raise | exit (first attempt only) | always (every attempt raises)


def attempt_chunk(spec: SweepSpec, chunk: int, inject: InjectedFailure | None = None) -> dict:
    """Run one chunk (the injected failure, if any, strikes the first attempt only)."""
    if inject is not None and inject.chunk == chunk and inject.mode == 'always':
        raise RuntimeError(f'injected failure of chunk {chunk} (every attempt)')
    if inject is not None and inject.chunk == chunk and not os.path.exists(inject.marker):
        Path(inject.marker).write_text(
            f'chunk {chunk} failed on purpose in process {os.getpid()}\n'
        )
        if inject.mode == 'exit':
            os._exit(17)
        raise RuntimeError(f'injected failure of chunk {chunk}')
    return run_chunk(spec, chunk)


class ChunkFailed(RuntimeError):
    """A chunk failed on every attempt."""


def run_local(
    spec: SweepSpec, chunks: Iterable[int], inject: InjectedFailure | None = None
) -> Iterator[tuple]:
    """Run chunks one after another in this process, retrying a failed one.

    Yield (chunk, columns).
    """
    for chunk in chunks:
        for attempt in range(MAX_RETRIES + 1):
            try:
                yield chunk, attempt_chunk(spec, chunk, inject)
                break
            except Exception as exc:  # noqa: BLE001 - any failure of an attempt is retried
                if attempt == MAX_RETRIES:
                    raise ChunkFailed(
                        f'chunk {chunk} failed {MAX_RETRIES + 1} times: {exc}'
                    ) from exc


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


def start_ray(target: str):
    """Start (local:N) or join (address) Ray.

    Return the ray module. StudyInputError when it cannot.
    """
    address, cpus = parse_ray_target(target)
    if cpus is None:
        check_reachable(address)
    import ray

    try:
        if cpus is not None:
            ray.init(
                address='local',
                num_cpus=cpus,
                include_dashboard=False,
                log_to_driver=False,
                object_store_memory=LOCAL_OBJECT_STORE_BYTES,
                configure_logging=False,
            )
        else:
            ray.init(address=address, log_to_driver=False, configure_logging=False)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise StudyInputError(
            f'cannot start or join Ray at {target}: {str(exc).splitlines()[0]}'
        ) from None
    return ray


def ray_workers(ray) -> int:
    """CPUs of the Ray cluster (one single-CPU task per CPU at a time)."""
    return int(ray.cluster_resources().get('CPU', 0))


def run_ray(
    ray, spec: SweepSpec, chunks: Iterable[int], inject: InjectedFailure | None = None
) -> Iterator[tuple]:
    """Submit every chunk as a Ray task (retried on failure).

    Yield (chunk, columns) as each finishes.
    """
    task = ray.remote(num_cpus=1, max_retries=MAX_RETRIES, retry_exceptions=True)(attempt_chunk)
    spec_ref = ray.put(spec)
    pending = {task.remote(spec_ref, chunk, inject): chunk for chunk in chunks}
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        ref = done[0]
        chunk = pending.pop(ref)
        try:
            columns = ray.get(ref)
        except Exception as exc:  # noqa: BLE001 - Ray wraps the task's own error
            for other in pending:
                ray.cancel(other)
            raise ChunkFailed(
                f'chunk {chunk} failed {MAX_RETRIES + 1} times on Ray: {str(exc).splitlines()[0]}'
            ) from exc
        yield chunk, columns
