# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""actuator_studies sweeps.

Encoder and delay hooks, sampling, batched rows against single runs, resume, bad input.
"""

import dataclasses
import json
import math
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest

from actuator_core.metrics import RunMetrics
from actuator_plant.drive import CommandDelay
from actuator_plant.encoder import Encoder, EncoderParameters
from actuator_plant.model import WorkingCondition
from actuator_sim.loop import ClosedLoop
from actuator_sim.offline import trace_metrics
from actuator_sim.scenarios import paper_scenario
from actuator_studies.cli import sweep_main
from actuator_studies.results import tables_identical
from actuator_studies.space import Axis, sample
from actuator_studies.sweep import SweepRequest, run_sweep, table_arrays

#: Just past the steady-state window start (5 s), to keep the tests short.
SHORT_S = 5.2


def test_encoder_quantises_within_half_a_count_and_adds_seeded_noise():
    q = np.linspace(-1.0, 1.0, 2001)
    enc = Encoder(counts_per_rev=4096)
    y = enc.measure(q)
    step = 2.0 * math.pi / 4096
    assert np.max(np.abs(y - q)) <= step / 2 + 1e-15
    assert np.allclose(np.round(y / step), y / step)
    noisy = [Encoder(0, 1e-3, seed=np.arange(2000)).measure(np.zeros(2000)) for _ in range(2)]
    assert np.array_equal(noisy[0], noisy[1])  # seeded: the same draws again
    assert 0.9e-3 < np.std(noisy[0]) < 1.1e-3
    alone = Encoder(0, 1e-3, seed=np.array([7])).measure(np.zeros(1))
    assert alone[0] == noisy[0][7]  # a run's noise does not depend on its batch
    assert Encoder().measure(0.123) == 0.123 and not EncoderParameters().active


def test_inactive_encoder_and_zero_delay_leave_the_paper_run_bit_identical():
    base = paper_scenario('p', 'pp_nftsmc_eso', 'fast', 'deep_sea', duration_s=0.3)
    ref = ClosedLoop(base).run()
    other = ClosedLoop(
        dataclasses.replace(base, encoder=EncoderParameters(), command_delay_samples=0)
    ).run()
    assert all(np.array_equal(ref[k], other[k], equal_nan=True) for k in ref)
    late = ClosedLoop(dataclasses.replace(base, command_delay_samples=1)).run()
    assert not np.array_equal(ref['measured_position_rad'], late['measured_position_rad'])


def test_command_delay_returns_the_command_of_d_samples_before_per_element():
    delay = CommandDelay(np.array([0, 1, 2]), np.zeros(3))
    out = [delay.apply(np.full(3, k + 1.0)) for k in range(4)]
    assert [list(o) for o in out] == [[1, 0, 0], [2, 1, 0], [3, 2, 1], [4, 3, 2]]
    with pytest.raises(ValueError):
        CommandDelay(1.5)


def test_latin_hypercube_puts_one_draw_in_each_stratum_and_is_seeded():
    axes = [Axis('depth_m', 0.0, 1000.0), Axis('condition.temperature_c', -2.0, 30.0)]
    t = sample(axes, 'lhs', 50, seed=4)
    for name, (low, high) in (
        ('depth_m', (0.0, 1000.0)),
        ('condition.temperature_c', (-2.0, 30.0)),
    ):
        strata = np.floor((t[name] - low) / (high - low) * 50).astype(int)
        assert sorted(strata) == list(range(50))
    again = sample(axes, 'lhs', 50, seed=4)
    assert all(np.array_equal(t[k], again[k]) for k in t)
    assert not np.array_equal(t['depth_m'], sample(axes, 'lhs', 50, seed=5)['depth_m'])


def _single_run_metrics(depth, temperature, noise, delay, seed) -> RunMetrics:
    """Return a run built by hand from the paper's scenario, as offline_sim runs one."""
    s = paper_scenario('one', 'pp_nftsmc_eso', 'fast', 'deep_sea', duration_s=SHORT_S)
    s = dataclasses.replace(
        s,
        plant=dataclasses.replace(
            s.plant, condition=WorkingCondition.at_depth(depth, temperature)
        ),
        encoder=EncoderParameters(
            counts_per_rev=65536, noise_std_rad=noise, seed=np.array([seed])
        ),
        command_delay_samples=delay,
    )
    with np.errstate(all='ignore'):
        trace = ClosedLoop(s).run()
    m = trace_metrics(trace)
    return dataclasses.replace(m, diverged=True) if len(trace['t_s']) < s.samples else m


@pytest.mark.slow
def test_grid_rows_equal_single_closed_loop_runs_of_the_same_points(tmp_path):
    req = SweepRequest(
        vary=[
            'depth_m=0,4000',
            'condition.temperature_c=-2,30',
            'encoder.noise_std_rad=0,2e-4',
            'command_delay_samples=0,2',
        ],
        set=['encoder.counts_per_rev=65536'],
        duration_s=SHORT_S,
        batch=8,
        seed=11,
    )
    summary = run_sweep(req, tmp_path / 'grid', progress=False)
    rows = table_arrays(tmp_path / 'grid')
    assert summary['runs'] == 16 and list(rows['run']) == list(range(16))
    # 4000 m: the seal friction wins, the joint falls behind and the following-error stop latches,
    # as the controller node does (the loop holds the same ControlSampleAssembly):
    # diverged, never a number.
    assert (
        list(rows['diverged']) == [d == 4000.0 for d in rows['depth_m']]
        and summary['saturated_runs'] >= 8
    )
    assert set(RunMetrics.__dataclass_fields__) - {'steady_window_s'} <= set(rows)
    for i in (0, 3, 6, 9, 15):
        single = _single_run_metrics(
            rows['depth_m'][i],
            rows['condition.temperature_c'][i],
            rows['encoder.noise_std_rad'][i],
            int(rows['command_delay_samples'][i]),
            int(rows['seed'][i]),
        )
        assert rows['diverged'][i] == single.diverged
        assert rows['max_steady_error_rad'][i] == pytest.approx(
            single.max_steady_error_rad, rel=1e-9, nan_ok=True
        )
        assert rows['rms_error_rad'][i] == pytest.approx(
            single.rms_error_rad, rel=1e-9, nan_ok=True
        )
        assert rows['saturated_fraction'][i] == pytest.approx(single.saturated_fraction, abs=1e-12)
        assert rows['bounds_violations'][i] == single.bounds_violations
    assert (tmp_path / 'grid' / 'figures' / 'map.png').stat().st_size > 10_000
    saved = json.loads((tmp_path / 'grid' / 'summary.json').read_text())
    assert (
        saved['diverged'] == 8 and saved['worst_run']['depth_m'] == 0.0
    )  # the worst run that has a figure
    assert saved['failed_runs'] == 8 + int(np.sum(rows['max_steady_error_rad'] > 1e-2))


@pytest.mark.ros
def test_an_interrupted_sweep_resumes_to_the_same_table(tmp_path):
    args = [
        '--vary',
        'drift.inertia_amplitude=0:0.6',
        '--vary',
        'external.mean_nm=0:40',
        '--method',
        'mc',
        '--samples',
        '6',
        '--seed',
        '3',
        '--batch',
        '2',
        '--duration',
        str(SHORT_S),
        '--no-progress',
    ]
    assert sweep_main(args + ['--out', str(tmp_path / 'full')]) == 0
    # The process dies while chunk 1 runs (as on a power cut): chunk 0 is on disk, nothing else.
    cmd = [
        sys.executable,
        '-c',
        'import sys; from actuator_studies.cli import sweep_main; '
        'sys.exit(sweep_main(sys.argv[1:]))',
        *args,
        '--out',
        str(tmp_path / 'cut'),
        '--inject-failure',
        f'1:exit:{tmp_path / "marker"}',
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 17
    assert sorted(p.name for p in (tmp_path / 'cut' / 'chunks').iterdir()) == [
        'chunk_00000.parquet'
    ]
    assert sweep_main(args + ['--out', str(tmp_path / 'cut'), '--resume']) == 0
    summary = json.loads((tmp_path / 'cut' / 'summary.json').read_text())
    assert summary['chunks_resumed'] == 1 and summary['execution']['runs_this_call'] == 4
    assert tables_identical(
        pq.read_table(tmp_path / 'cut' / 'runs.parquet'),
        pq.read_table(tmp_path / 'full' / 'runs.parquet'),
    )
    assert (tmp_path / 'cut' / 'figures' / 'cdf.png').exists()
    # A resume that asks a different study is refused.
    assert (
        sweep_main(
            [a.replace('0:40', '0:50') for a in args]
            + ['--out', str(tmp_path / 'cut'), '--resume']
        )
        == 2
    )


@pytest.mark.parametrize(
    'args, expected',
    [
        (['--vary', 'dpth_m=0:100:3'], "did you mean 'depth_m'"),
        (['--vary', 'pp_nftsmc_eso.k0=50:100:3'], "did you mean 'pp_nftsmc_eso.k0_per_s'"),
        (['--vary', 'depth_m=1000:1000:3'], 'empty range'),
        (['--vary', 'depth_m=2000:0:3'], 'inverted range'),
        (['--vary', 'depth_m=0:100:0'], 'point count'),
        (['--vary', 'depth_m=0:100', '--method', 'mc', '--samples', '0'], 'sample count'),
        (['--vary', 'depth_m=0:20000:3'], 'valid range'),
        (['--vary', 'depth_m=0:100:2', '--ray', '127.0.0.1:9'], 'unreachable'),
        (['--vary', 'oil.nu40_mm2_s=20:24:3'], 'cannot vary inside a vectorised batch'),
        (['--vary', 'common.current_limit_a=10,20'], 'cannot vary inside a vectorised batch'),
        (
            [
                '--vary',
                'geometry.rotor_end_diameter_m=0.05:0.06',
                '--method',
                'mc',
                '--samples',
                '4',
            ],
            'cannot vary inside a vectorised batch',
        ),  # fmt: skip
    ],
)
def test_bad_input_is_one_line_on_stderr_exit_2_and_writes_nothing(
    tmp_path, capsys, args, expected
):
    out = tmp_path / 'study'
    assert sweep_main(args + ['--out', str(out), '--duration', str(SHORT_S), '--no-progress']) == 2
    err = capsys.readouterr().err
    assert (
        len(err.strip().splitlines()) == 1 and expected in err and err.startswith('sweep: error:')
    )
    assert not out.exists()


def test_an_existing_output_folder_is_refused_and_left_untouched(tmp_path, capsys):
    out = tmp_path / 'study'
    out.mkdir()
    (out / 'runs.parquet').write_text('earlier results')
    assert (
        sweep_main(['--vary', 'depth_m=0:100:2', '--out', str(out), '--duration', str(SHORT_S)])
        == 2
    )
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and 'exists' in err
    assert [p.name for p in out.iterdir()] == ['runs.parquet'] and (
        out / 'runs.parquet'
    ).read_text() == 'earlier results'


@pytest.mark.ros
def test_the_installed_sweep_executable_reports_bad_input_with_exit_2(tmp_path):
    from ros_helpers import executable_path

    proc = subprocess.run(
        [
            str(executable_path('actuator_studies', 'sweep')),
            '--vary',
            'condition.temprature_c=0:5:2',
            '--out',
            str(tmp_path / 'x'),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2 and proc.stderr.strip().count('\n') == 0
    assert "did you mean 'condition.temperature_c'" in proc.stderr


def test_tables_identical_takes_nan_as_equal_and_finds_a_one_ulp_difference():
    import pyarrow as pa

    a = pa.table({'x': [1.0, float('nan')], 'run': [0, 1]})
    assert not a.equals(a) and tables_identical(a, a)
    b = pa.table({'x': [np.nextafter(1.0, 2.0), float('nan')], 'run': [0, 1]})
    assert not tables_identical(a, b)


@pytest.mark.slow
def test_task_size_is_separate_from_the_batch_and_study_json_records_its_provenance(tmp_path):
    common = dict(
        vary=['depth_m=0:2000:5', 'encoder.noise_std_rad=1e-4'],
        set=['encoder.counts_per_rev=65536'],
        duration_s=SHORT_S,
        seed=9,
    )
    run_sweep(SweepRequest(batch=5, **common), tmp_path / 'one', progress=False)
    summary = run_sweep(
        SweepRequest(batch=2, chunk=3, **common), tmp_path / 'split', progress=False
    )
    assert summary['chunks'] == 2 and summary['chunk_runs'] == 3  # 3 + 2 runs, batches of 2
    a, b = (table_arrays(tmp_path / d) for d in ('one', 'split'))
    # Same runs, same seeds, same verdicts; numpy's SIMD loops may round an element differently
    # by its position in the array, so another batching can move the last bits
    # (docs/studies.md#how-a-sweep-runs).
    for key in ('run', 'seed', 'depth_m', 'diverged', 'saturated_samples', 'bounds_violations'):
        assert np.array_equal(a[key], b[key])
    for key in ('max_steady_error_rad', 'rms_error_rad', 'rms_current_a'):
        assert np.allclose(a[key], b[key], rtol=1e-9, atol=0.0)
    b = pq.read_table(tmp_path / 'split' / 'runs.parquet')
    seeds = b.column('seed').to_pylist()
    assert b.schema.field('seed').type == 'uint64' and len(set(seeds)) == 5
    assert max(seeds) >= 2**40  # wider than the 32-bit seeds of before (2^32 - 1 at most)
    study = json.loads((tmp_path / 'split' / 'study.json').read_text())
    prov = study['provenance']
    assert len(prov['commit']) == 40 and len(prov['lock_sha256']) == 64
    assert prov['libraries']['numpy'] == np.__version__ and prov['seeds']['study'] == 9
    # A resume with another commit or command line is the same study; another request is not.
    study['provenance']['commit'] = '0' * 40
    (tmp_path / 'split' / 'study.json').write_text(json.dumps(study))
    again = run_sweep(
        SweepRequest(batch=2, chunk=3, **common), tmp_path / 'split', resume=True, progress=False
    )
    assert again['chunks_resumed'] == 2


@pytest.mark.slow
def test_repeat_runs_each_point_with_its_own_noise_seed(tmp_path):
    req = SweepRequest(
        vary=['depth_m=0,1000'],
        set=['encoder.counts_per_rev=65536', 'encoder.noise_std_rad=2e-4'],
        repeat=3,
        duration_s=SHORT_S,
        seed=4,
    )
    summary = run_sweep(req, tmp_path / 'r', progress=False)
    rows = table_arrays(tmp_path / 'r')
    assert summary['runs'] == 6 and list(rows['depth_m']) == [0.0] * 3 + [1000.0] * 3
    assert len(set(rows['seed'])) == 6
    assert len(set(rows['max_steady_error_rad'][:3])) == 3  # the noise differs, so do the runs


@pytest.mark.slow
def test_sweep_compare_tells_identical_studies_from_one_changed_cell(tmp_path, capsys):
    """``sweep-compare A B``: 0 for identical studies, 1 after one cell changed.

    The cell moves by one ulp (a changed platform or law); a folder without a study is exit 2
    with one line on stderr naming the file it could not read.
    """
    import shutil

    import pyarrow as pa

    from actuator_studies.cli import compare_main

    req = SweepRequest(vary=['depth_m=0,1000'], duration_s=SHORT_S, seed=5)
    run_sweep(req, tmp_path / 'a', progress=False)
    shutil.copytree(tmp_path / 'a', tmp_path / 'b')
    capsys.readouterr()
    assert compare_main([str(tmp_path / 'a'), str(tmp_path / 'b')]) == 0
    table = pq.read_table(tmp_path / 'a' / 'runs.parquet')
    columns = len(table.column_names)
    assert capsys.readouterr().out == (
        f'sweep-compare: 2 and 2 rows, {columns} columns: identical\n'
    )
    # one cell of the copy, one ulp up: what a changed platform or a changed law would give
    errors = table.column('max_steady_error_rad').to_numpy().copy()
    assert np.all(np.isfinite(errors))
    errors[1] = np.nextafter(errors[1], np.inf)
    index = table.column_names.index('max_steady_error_rad')
    changed = table.set_column(index, 'max_steady_error_rad', pa.array(errors))
    pq.write_table(changed, tmp_path / 'b' / 'runs.parquet')
    assert compare_main([str(tmp_path / 'a'), str(tmp_path / 'b')]) == 1
    assert capsys.readouterr().out == (
        f'sweep-compare: 2 and 2 rows, {columns} columns: DIFFERENT\n'
    )
    missing = tmp_path / 'never_run'
    assert compare_main([str(tmp_path / 'a'), str(missing)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ''
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('sweep-compare: error:'), err
    assert str(missing / 'runs.parquet') in err[0], err
