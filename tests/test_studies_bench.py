# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""sweep-bench: what it times, and its command line."""

import json

import pytest

from actuator_studies import bench, distributed
from actuator_studies.cli import bench_main


@pytest.mark.parametrize('workers', [1, 2, 3])
def test_every_ray_worker_count_gets_the_same_chunks_per_worker(workers):
    # Before, the runs were fixed and split over the workers: two workers got half the batch,
    # which by itself costs per-run throughput, and the efficiency read 0.26-0.52.
    spec = bench.ray_spec(workers, 8192, 2.0)
    assert spec.batch == spec.chunk_size == 8192 // distributed.IN_FLIGHT_PER_CPU
    assert spec.runs == 8192 * workers
    assert spec.chunks == distributed.IN_FLIGHT_PER_CPU * workers
    assert spec.base.duration_s == 2.0


def test_the_command_prints_the_tables_and_writes_the_figures(tmp_path, capsys):
    out = tmp_path / 'bench.json'
    args = ['--batches', '4,8', '--workers', '', '--duration', '0.02', '--json', str(out)]
    assert bench_main(args) == 0
    text = capsys.readouterr().out
    assert '| vectorised batch' in text and 'load average' in text
    figures = json.loads(out.read_text())
    assert set(figures['batch_runs_per_s_per_core']) == {'4', '8'}
    assert all(v > 0 for v in figures['batch_runs_per_s_per_core'].values())
    assert figures['scalar_runs_per_s'] > 0 and figures['ray_runs_per_s'] == {}


@pytest.mark.parametrize(
    'bad', [['--batches', '0'], ['--runs-per-worker', '0'], ['--batches', 'x']]
)
def test_bad_arguments_are_one_line_and_exit_2(bad, capsys):
    with pytest.raises(SystemExit) as exit_info:
        code = bench_main(['--workers', '', '--duration', '0.02', *bad])
        raise SystemExit(code)
    assert exit_info.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
