# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""actuator_studies on Ray (one local instance, two workers).

Equal to a local run, failed chunks retried, never missing.
"""

import pyarrow.parquet as pq
import pytest

from actuator_studies import distributed
from actuator_studies.distributed import ChunkFailed, InjectedFailure
from actuator_studies.results import tables_identical
from actuator_studies.sweep import SweepRequest, run_sweep

pytestmark = pytest.mark.ros  # a local Ray instance: worker processes

SHORT_S = 5.2


@pytest.fixture(scope='module')
def ray_session():
    """Return a private local Ray instance with two workers for the whole module."""
    ray = distributed.start_ray('local:2')
    assert distributed.ray_workers(ray) == 2
    yield ray
    ray.shutdown()


def _request(**changes) -> SweepRequest:
    """Return a small Monte Carlo with encoder noise (so the per-run seeds matter)."""
    fields = dict(
        vary=[
            'condition.temperature_c=-2:30',
            'drift.torque_constant_amplitude=0:0.6',
            'encoder.noise_std_rad=0:2e-4',
        ],
        method='lhs',
        samples=6,
        seed=5,
        batch=2,
        duration_s=SHORT_S,
    )
    fields.update(changes)
    return SweepRequest(**fields)


@pytest.fixture(scope='module')
def local_table(tmp_path_factory):
    """Return the same study run in this process."""
    out = tmp_path_factory.mktemp('local') / 'study'
    run_sweep(_request(), out, progress=False)
    return pq.read_table(out / 'runs.parquet')


def test_ray_run_equals_the_local_run_row_for_row(ray_session, local_table, tmp_path):
    summary = run_sweep(_request(), tmp_path / 'ray', progress=False, ray_session=ray_session)
    assert summary['execution']['workers'] == 2 and summary['runs'] == 6
    table = pq.read_table(tmp_path / 'ray' / 'runs.parquet')
    assert tables_identical(table, local_table)
    assert len(set(table.column('seed').to_pylist())) == 6


def test_a_chunk_whose_worker_dies_is_run_again_to_the_same_table(
    ray_session, local_table, tmp_path
):
    marker = tmp_path / 'lost-once'
    run_sweep(
        _request(),
        tmp_path / 'ray',
        progress=False,
        ray_session=ray_session,
        inject=InjectedFailure(chunk=1, marker=str(marker), mode='exit'),
    )
    assert marker.exists()  # the first attempt's process did die
    assert tables_identical(pq.read_table(tmp_path / 'ray' / 'runs.parquet'), local_table)


def test_a_chunk_that_raises_ends_the_study_at_once_with_the_remote_error_in_full(
    ray_session, tmp_path
):
    out = tmp_path / 'ray'
    marker = tmp_path / 'attempts'
    with pytest.raises(ChunkFailed) as failed:
        run_sweep(
            _request(),
            out,
            progress=False,
            ray_session=ray_session,
            inject=InjectedFailure(chunk=2, marker=str(marker), mode='raise'),
        )
    text = str(failed.value)
    assert text.startswith('chunk 2 failed on Ray:')
    assert 'RuntimeError: injected failure of chunk 2' in text and 'ip=127.0.0.1' in text
    assert 'attempt_chunk' in text  # the worker's own traceback, not a cut first line
    assert marker.read_text().count('\n') == 1  # one attempt: a raise is not retried
    assert not (out / 'runs.parquet').exists() and not (out / 'summary.json').exists()
    assert not (out / 'chunks' / 'chunk_00002.parquet').exists()


def test_in_flight_tasks_are_bounded_and_every_task_declares_its_memory(ray_session):
    import time

    calls = []

    @ray_session.remote
    def probe(i):
        time.sleep(0.05)
        return i

    submitted = []
    real_remote = probe.options

    def counting_options(**options):
        calls.append(options)
        task = real_remote(**options)

        class Counting:
            def remote(self, *args):
                submitted.append(args[0])
                return task.remote(*args)

        return Counting()

    probe.options = counting_options
    seen_before_first = []
    out = []
    for args, result in distributed.stream_tasks(
        ray_session, probe, ((i,) for i in range(12)), in_flight=3, memory_bytes=123 * 2**20
    ):
        if not out:
            seen_before_first.append(len(submitted))
        out.append(result)
        assert len(submitted) - len(out) <= 3  # never more than 3 submitted and unfinished
    assert sorted(out) == list(range(12)) and seen_before_first == [4]
    assert calls == [
        {
            'num_cpus': 1,
            'max_retries': distributed.MAX_RETRIES,
            'retry_exceptions': False,
            'memory': 123 * 2**20,
        }
    ]


def test_design_batches_on_ray_equal_the_local_batch(ray_session):
    import numpy as np

    from actuator_studies.design import Evaluator, corner_table
    from actuator_studies.space import BaseScenario

    corners = corner_table(['depth_m=0,1000', 'encoder.noise_std_rad=1e-4'], 'pp_nftsmc_eso')
    sets = [
        {
            'pp_nftsmc_eso.k0_per_s': k0,
            'pp_nftsmc_eso.k1': 1000.0,
            'pp_nftsmc_eso.k2': 20.0,
            'pp_nftsmc_eso.k3_per_s': 200.0,
            'eso.omega0_rad_s': 60.0,
        }
        for k0 in (60.0, 100.0)
    ]
    base = BaseScenario(duration_s=SHORT_S)
    local = Evaluator(base, corners).run(sets)
    remote = Evaluator(base, corners, ray_session, workers=2).run(sets)
    for a, b in zip(local, remote):
        assert np.array_equal(a['error_rad'], b['error_rad'])
        assert np.array_equal(a['saturated_fraction'], b['saturated_fraction'])
    assert not np.array_equal(local[0]['error_rad'], local[1]['error_rad'])
