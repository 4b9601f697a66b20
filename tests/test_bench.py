# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The benchmark's figures, input checks and one short sim-time run.

The figure computations run on synthetic arrays.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from actuator_bench import bench, bench_figures, bench_run, bench_table, bench_variants

PERIOD_NS = 1_000_000


def ticks_ns(periods_us: list[float]) -> np.ndarray:
    """Arrival wall times [ns] whose consecutive differences are ``periods_us``."""
    return np.concatenate(([0], np.cumsum(np.asarray(periods_us) * 1000))).astype(np.int64)


def test_period_gap_of_2_5_ms_counts_once():
    f = bench_figures.period_figures(ticks_ns([1000.0] * 98 + [2500.0]), PERIOD_NS)
    assert f['periods_over_2x'] == 1
    assert f['period_max_us'] == pytest.approx(2500.0)
    assert f['period_mean_us'] == pytest.approx((98 * 1000.0 + 2500.0) / 99)
    assert f['period_p50_us'] == pytest.approx(1000.0)


def test_period_of_exactly_2_ms_is_not_over():
    figures = bench_figures.period_figures(ticks_ns([1000.0, 2000.0, 1000.0]), PERIOD_NS)
    assert figures['periods_over_2x'] == 0


def test_period_p99_deviation_is_of_the_absolute_deviation():
    # half the periods exact, half 200 us short: the signed deviation's p99 would be 0
    f = bench_figures.period_figures(ticks_ns([800.0, 1000.0] * 50), PERIOD_NS)
    assert f['period_mean_us'] == pytest.approx(900.0)
    assert f['period_dev_p99_us'] == pytest.approx(200.0)


def test_period_of_too_few_ticks_is_missing():
    f = bench_figures.period_figures(np.array([5], dtype=np.int64), PERIOD_NS)
    assert f['period_mean_us'] is None and f['periods_over_2x'] is None


def test_latency_percentiles_and_late_count():
    latency_ns = np.arange(1, 101, dtype=np.int64) * 10_000  # 10 us .. 1000 us
    latency_ns[-1] = 1_500_000  # one command 1.5 ms after its stamp
    f = bench_figures.latency_figures(latency_ns, PERIOD_NS)
    assert f['latency_p50_us'] == pytest.approx(505.0)  # linear interpolation between 500 and 510
    assert f['latency_p99_us'] == pytest.approx(990.0 + 0.01 * (1500.0 - 990.0))
    assert f['latency_max_us'] == pytest.approx(1500.0)
    assert f['latency_over_period'] == 1


def test_missed_samples_from_stamp_gaps():
    stamps = (
        np.array([0, 1, 2, 5, 6, 6, 8], dtype=np.int64) * PERIOD_NS
    )  # a repeated stamp is no gap
    assert bench_figures.missed_samples(stamps, PERIOD_NS) == 3


def test_held_command_fractions():
    stamps = np.arange(11, dtype=np.int64) * PERIOD_NS
    age = np.array(
        [0, 1, 1, 1, 1, 1, 2, 2, 3, 0, 0]
    )  # sample 0 is left out; ages of samples 1..10
    held = stamps - age * PERIOD_NS
    held[0] = -1
    held[9] = -1  # no command held (timeout)
    held[10] = stamps[10] - 1  # not on the grid: odd
    f = bench_figures.held_command_fractions(stamps, held, PERIOD_NS)
    assert f['held_same_pct'] == pytest.approx(50.0)
    assert f['held_next_pct'] == pytest.approx(20.0)
    assert f['held_later_pct'] == pytest.approx(10.0)
    assert f['held_none_pct'] == pytest.approx(10.0)
    assert f['held_odd_pct'] == pytest.approx(10.0)
    assert f['held_in_time_pct'] == pytest.approx(70.0)


def test_sim_speed_from_plant_span():
    stamps = 1_000_000_000 + np.arange(1001, dtype=np.int64) * PERIOD_NS  # 1 s simulated
    wall = 5_000 + np.arange(1001, dtype=np.int64) * 250_000  # in 0.25 s of wall time
    f = bench_figures.plant_figures(stamps, wall, PERIOD_NS)
    assert f['speed_x'] == pytest.approx(4.0)
    assert f['plant_interval_p50_us'] == pytest.approx(250.0)


def test_the_joints_gaps_are_counted_in_the_steady_window_only():
    stamps = np.arange(10_001, dtype=np.int64) * PERIOD_NS  # 10 s
    wall = stamps.copy()
    wall[2_000:] += 20 * PERIOD_NS  # a 21 ms gap at 2 s: before the steady window
    wall[6_000:] += 7 * PERIOD_NS  # 8 ms at 6 s: beyond the 7 ms measurement timeout
    wall[8_000:] += 6 * PERIOD_NS  # 7 ms at 8 s: not beyond it
    f = bench_figures.plant_figures(stamps, wall, PERIOD_NS)
    assert f['steady_gap_max_ms'] == pytest.approx(8.0)
    assert f['steady_gaps_beyond_timeout'] == 1
    assert f['plant_interval_max_us'] == pytest.approx(21_000.0)  # the whole run's


def test_latency_breakdown_joins_by_stamp():
    stamps = np.arange(5, dtype=np.int64) * PERIOD_NS
    published = stamps + 20_000  # plant 20 us late
    ctrl_stamps = stamps[1:]  # controller never saw sample 0
    received = ctrl_stamps + 20_000 + 100_000  # 100 us transport
    latency = np.full(4, 20_000 + 100_000 + 30_000)  # 30 us in the controller
    f = bench_figures.latency_breakdown(stamps, published, ctrl_stamps, received, latency)
    assert f['plant_late_p99_us'] == pytest.approx(20.0)
    assert f['transport_p99_us'] == pytest.approx(100.0)
    assert f['controller_wait_p50_us'] == pytest.approx(30.0)


def test_coverage_of_the_controller_log():
    f = bench_figures.coverage_figures(
        np.arange(500, dtype=np.int64) * PERIOD_NS, np.arange(2000, dtype=np.int64) * PERIOD_NS
    )
    assert f['controlled_pct'] == pytest.approx(25.0)
    assert f['controlled_span_s'] == pytest.approx(0.499)


def test_log_figures(tmp_path):
    (tmp_path / 'plant.stderr').write_text('[INFO] running under SCHED_FIFO priority 50\n')
    (tmp_path / 'controller.stderr').write_text(
        '[ERROR] |error| 0.501 rad beyond following_error_limit_rad 0.5: '
        'safe stop latched (0 A) until restart\n'
    )
    assert bench_figures.log_figures(tmp_path) == {'fifo_nodes': 1.0, 'safe_stop': 1.0}


def test_eso_figures():
    f = bench_figures.eso_figures(
        {
            'steps': 200,
            'exact_pairs': 150,
            'substituted_pairs': 50,
            'repaired_pairs': 40,
            'refused_inputs': 2,
        }
    )
    assert f['eso_exact_pct'] == pytest.approx(75.0)
    assert f['eso_exact_or_repaired_pct'] == pytest.approx(95.0) and f['eso_repaired'] == 40
    assert f['eso_substituted'] == 50 and f['eso_refused'] == 2
    assert bench_figures.eso_figures({'steps': 0})['eso_exact_pct'] is None


def test_error_ratios():
    r = bench_figures.error_ratios(
        {'max_steady_error_rad': 1.1e-3, 'rms_error_rad': 4e-4},
        {'max_steady_error_rad': 1e-3, 'rms_error_rad': float('nan')},
    )
    assert r['error_ratio_max_steady'] == pytest.approx(1.1)
    assert r['error_ratio_rms'] is None


def test_spread_and_verdict():
    values = [3.0, None, 1.0, float('nan'), 2.0]
    s = bench_table.spread(values)
    assert (s.median, s.low, s.high, s.n) == (2.0, 1.0, 3.0, 3)
    at_most_2 = bench_table.Target('<= 2', high=2.0)
    assert bench_table.verdict(at_most_2, values) == 'PASS 2/3'
    assert bench_table.verdict(bench_table.Target('<= 1.5', high=1.5), values) == 'MISS 1/3'
    assert bench_table.verdict(at_most_2, [None]) == 'n/a'
    assert bench_table.verdict(None, values) == ''


def test_table_lines_carry_target_and_verdict():
    rows = [
        bench_table.Row(
            'latency_p99_us', 'latency p99', 'us', '.1f', bench_table.Target('<= 300', high=300.0)
        ),
        bench_table.Row('absent', 'absent figure', 'us'),
    ]
    table = bench_table.format_table(
        [('realtime', rows, [{'latency_p99_us': 250.0}, {'latency_p99_us': 400.0}])]
    )
    line = next(line for line in table.splitlines() if 'latency p99' in line)
    assert '325.0' in line and '250.0' in line and '400.0' in line and 'MISS 1/2' in line
    assert 'absent figure' not in table


def test_a_composed_process_is_judged_as_the_joint_loop_not_as_one_node():
    """A composed run: its process's CPU meets the loop's 50 %, not a node's 25 %."""
    figures = bench_figures.process_figures({'loop': 43.0, 'recorder': 13.0}, {'loop': 86.0})
    assert figures['cpu_joint_loop_pct'] == 43.0
    table = bench_table.format_table([('composed', bench_table.realtime_rows(1000.0), [figures])])
    lines = {line.split('  ')[0].strip(): line for line in table.splitlines()}
    assert lines['CPU joint + ESO + controller'].rstrip().endswith('PASS 1/1')
    assert 'MISS' not in lines['CPU loop'] and 'PASS' not in lines['CPU loop']
    assert 'MISS' not in lines['peak RSS loop']  # 86 MB for three nodes


def test_variants():
    variants = bench_variants.make_variants(['realtime', 'sim'], ['normal', 'fifo'], 50)
    assert [v.slug for v in variants] == ['sim', 'realtime_normal', 'realtime_fifo50']
    assert 'SCHED_FIFO 50' in variants[2].title
    pinned = bench_variants.make_variants(
        ['realtime'], ['fifo-pinned-composed', 'fifo-pinned'], 50
    )
    assert [(v.slug, v.pinned, v.composed) for v in pinned] == [
        ('realtime_fifo50_pinned_composed', True, True),
        ('realtime_fifo50_pinned', True, False),
    ]
    assert 'the process on CPU 0' in pinned[0].title and 'ESO, controller CPU 1' in pinned[1].title


def test_variants_per_diagnostics_rate_and_publication_mode():
    """Each real-time variant once more per rate; every variant once per publication mode."""
    variants = bench_variants.make_variants(
        ['realtime', 'sim'], ['fifo', 'fifo-composed'], 50, [100.0, 0.0], ['SYNCHRONOUS']
    )
    assert [v.slug for v in variants] == [
        'sim_synchronous',
        'realtime_fifo50_synchronous',
        'realtime_fifo50_diag100hz_synchronous',
        'realtime_fifo50_diag0hz_synchronous',
        'realtime_fifo50_composed_synchronous',
        'realtime_fifo50_composed_diag100hz_synchronous',
        'realtime_fifo50_composed_diag0hz_synchronous',
    ]
    assert 'controller/state and plant/truth at 100 Hz' in variants[2].title
    assert 'at 1 kHz' in variants[3].title and 'synchronous publication' in variants[3].title
    modes = bench_variants.make_variants(['sim'], [], 50, [100.0], ['SYNCHRONOUS', 'ASYNCHRONOUS'])
    assert [v.slug for v in modes] == ['sim_synchronous', 'sim_asynchronous']  # no rate in sim


def test_variants_per_transport_and_the_shared_memory_environment():
    """--transports: a variant per transport; shared memory is a choice the runner keeps."""
    from actuator_ros.middleware import realtime_transport

    variants = bench_variants.make_variants(
        ['sim', 'realtime'], ['fifo'], 50, (), (), False, ['udp', 'shared-memory']
    )
    assert [v.slug for v in variants] == [
        'sim',  # sim time keeps shared memory: a "udp" sim run would be mislabelled
        'realtime_fifo50_udp',
        'realtime_fifo50_shared_memory',
    ]
    assert variants[2].title.endswith('Fast DDS over shared memory')
    assert bench_run.transport_environment('udp') == {}  # the runner's own in real time
    shared = bench_run.transport_environment('shared-memory')
    env = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', **shared}
    assert realtime_transport(env, Path('profile.xml')).set == {}  # kept: shared memory stays
    assert realtime_transport({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}, Path('p')).set


def test_each_variant_once_more_without_the_recorder():
    """--without-recorder: each variant followed by its unrecorded twin, named and titled so."""
    variants = bench_variants.make_variants(
        ['sim-composed', 'realtime'], ['fifo'], 50, (), (), True
    )
    assert [(v.slug, v.recorded) for v in variants] == [
        ('sim_composed', True),
        ('sim_composed_unrecorded', False),
        ('realtime_fifo50', True),
        ('realtime_fifo50_unrecorded', False),
    ]
    assert variants[3].title.endswith(', no recorder')


def test_the_in_process_recording_is_a_sim_variant_of_its_own_and_unrecorded_only_once():
    """sim-composed-in-process: its slug and title; unrecorded, it is sim_composed's twin."""
    variants = bench_variants.make_variants(
        ['sim-composed', 'sim-composed-in-process'], [], 50, (), (), True
    )
    assert [(v.slug, v.in_process) for v in variants] == [
        ('sim_composed', False),
        ('sim_composed_unrecorded', False),
        ('sim_composed_in_process', True),
    ]
    assert variants[2].title.endswith('in one process, recorded in-process (no recorder process)')


def test_a_publication_mode_reaches_the_processes_and_is_restored(monkeypatch):
    """The variant's mode is in os.environ only while its run starts processes."""
    name = 'RMW_FASTRTPS_PUBLICATION_MODE'
    monkeypatch.setenv(name, 'SYNCHRONOUS')
    with bench_run._environment(bench_run.publication_mode_environment('ASYNCHRONOUS')):
        assert os.environ[name] == 'ASYNCHRONOUS'
    assert os.environ[name] == 'SYNCHRONOUS'
    monkeypatch.delenv(name)
    with bench_run._environment(bench_run.publication_mode_environment('ASYNCHRONOUS')):
        assert os.environ[name] == 'ASYNCHRONOUS'
    assert name not in os.environ
    assert bench_run.publication_mode_environment('') == {}  # the runner's own mode


@pytest.mark.slow
def test_offline_speed_is_positive():
    assert math.isfinite(bench_run.offline_speed('case2_pp_nftsmc_eso', None, 0.02))
    assert bench_run.offline_speed('case2_pp_nftsmc_eso', 10, 0.02) > 0


@pytest.mark.slow
@pytest.mark.parametrize(
    'argv',
    [
        ['--scenario', 'no_such_scenario'],
        ['--duration', '0'],
        ['--duration', '4000'],
        ['--repeats', '0'],
        ['--rt-priority', '100'],
        ['--floor-s', '0.5'],
        ['--diagnostics-rates', '-1'],
        ['--diagnostics-rates', '100', '20000'],
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, capsys, tmp_path):
    assert bench.main([*argv, '--out', str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith('bench: error:') and err.count('\n') == 1
    assert not any(tmp_path.iterdir())


def test_hop_figures_halve_the_round_trip_and_count_lost_messages():
    figures = bench_figures.hop_figures(np.array([2_000, 4_000, 6_000]), sent=4)
    assert figures['floor_lost_pct'] == pytest.approx(25.0)
    assert figures['floor_hop_p50_us'] == pytest.approx(2.0)
    assert figures['floor_hop_max_us'] == pytest.approx(3.0)
    assert bench_figures.hop_figures(np.array([], dtype=np.int64), sent=5) == {
        'floor_lost_pct': 100.0
    }
    assert bench_figures.hop_figures(np.array([], dtype=np.int64), sent=0) == {}


def test_steal_share_between_two_readings():
    assert bench_run.steal_percent((10, 1000), (30, 2000)) == pytest.approx(2.0)
    assert bench_run.steal_percent((0, 0), (0, 0)) is None
    steal, total = bench_run.cpu_times()
    assert 0 <= steal <= total


def test_short_sim_run_end_to_end(ros_env, tmp_path):
    out = tmp_path / 'bench'
    proc = subprocess.run(
        [
            sys.executable,
            '-m',
            'actuator_bench.bench',
            '--duration',
            '2',
            '--repeats',
            '1',
            '--skip-offline',
            '--modes',
            'sim',
            '--floor-s',
            '2',
            '--without-recorder',
            '--out',
            str(out),
        ],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert 'speed: sim s / wall s' in proc.stdout and '>= 3' in proc.stdout
    assert '[bench] run 1/2' in proc.stdout
    (base,) = out.iterdir()
    summary = json.loads((base / 'summary.json').read_text())
    run, unrecorded = summary['runs']
    assert run['error'] is None and unrecorded['error'] is None
    assert run['figures']['speed_x'] > 0
    assert run['figures']['eso_steps'] == 2000
    # Without the recorder: timing and the nodes' own counts, no bag and so no tracking figure.
    assert unrecorded['variant'] == 'sim_unrecorded' and unrecorded['figures']['speed_x'] > 0
    assert unrecorded['figures']['eso_steps'] == 2000
    assert 'max_steady_error_rad' in run['figures']
    assert run['figures']['observer_input_differing'] == 0  # the lockstep: always the held one
    assert 'max_steady_error_rad' not in unrecorded['figures']
    assert summary['sections']['sim']['figures']['speed_x']['n'] == 1
    assert (base / 'runs.csv').read_text().startswith('variant,')
    assert (base / 'table.txt').is_file()
    assert list(base.glob('runs/sim_rep1/*/plant_samples.npz'))
    # The middleware floor: echoes came back, and the echo node's CPU was measured.
    (hops,) = summary['floor_runs']
    assert hops['floor_hop_p50_us'] > 0 and hops['floor_lost_pct'] < 50.0
    assert hops['cpu_echo_pct'] > 0
    # The host floor: a lone grid thread on CPU 0 and on any CPU, each for the floor's length.
    for label in ('host_cpu0', 'host_any'):
        assert hops[f'{label}_wakeups'] == 2000  # the whole grid: 2 s at 1 kHz
        assert {f'{label}_stall_max_ms', f'{label}_beyond_timeout_per_min'} <= set(hops)
    assert 'grid thread on CPU 0' in proc.stdout
    assert 'middleware floor' in proc.stdout


@pytest.mark.slow
def test_missing_tool_skips_its_variant_with_one_line_and_each_run_is_saved_as_it_ends(
    monkeypatch, capsys, tmp_path
):
    """No ros2 on PATH: fifo-launch is skipped; every finished run is on disk before the next."""
    monkeypatch.setenv('PATH', str(tmp_path / 'no-tools'))
    calls = []

    def fake_run(variant, repeat, args, base, period_ns):
        if calls:  # the run before this one is already written
            saved = (base / 'runs.jsonl').read_text().splitlines()
            assert [json.loads(x)['variant'] for x in saved] == [c.slug for c in calls]
            assert (base / 'runs.csv').read_text().count('\n') == len(calls) + 1
        calls.append(variant)
        return bench_run.RunRecord(variant.slug, repeat, error='fake run')

    monkeypatch.setattr(bench, 'run_one', fake_run)  # where main looks it up
    argv = [
        '--modes',
        'realtime',
        '--rt-variants',
        'normal',
        'fifo-launch',
        'fifo',
        '--repeats',
        '2',
        '--duration',
        '1',
        '--floor-s',
        '0',
        '--skip-offline',
        '--quiet',
        '--out',
        str(tmp_path),
    ]
    assert bench.main(argv) == 1  # the fake runs report an error
    err = capsys.readouterr().err
    skips = [x for x in err.splitlines() if 'skipping' in x]
    assert skips == [
        'bench: skipping realtime_fifo50_launch: ros2 launch is not installed (no ros2 on PATH)'
    ]
    assert [v.slug for v in calls] == ['realtime_normal', 'realtime_fifo50'] * 2
    (base,) = [p for p in tmp_path.iterdir() if p.is_dir() and p.name != 'no-tools']
    assert len((base / 'runs.jsonl').read_text().splitlines()) == 4


def test_a_run_that_raises_is_that_runs_error(monkeypatch, tmp_path):
    """An unexpected exception in one run (a tool that vanished) is recorded, not raised."""
    import actuator_bringup.runner as bringup

    def boom(*args, **kwargs):
        raise FileNotFoundError(2, 'No such file or directory', 'ros2')

    monkeypatch.setattr(bringup, 'run_launched', boom)
    args = bench.build_parser().parse_args(['--duration', '1', '--quiet'])
    record = bench_run.run_one(
        bench_variants.Variant('realtime', 50, False, True), 1, args, tmp_path, 10**6
    )
    assert record.error.startswith('run failed: FileNotFoundError') and 'ros2' in record.error


def test_the_tick_period_max_after_the_start_leaves_out_the_first_second():
    """A 50 ms start-up stall at 0.2 s is the max; after the first second the max is 2.5 ms."""
    periods = [1000.0] * 200 + [50_000.0] + [1000.0] * 900 + [2500.0] + [1000.0] * 100
    f = bench_figures.period_figures(ticks_ns(periods), PERIOD_NS)
    assert f['period_max_us'] == pytest.approx(50_000.0)
    assert f['period_max_after_start_us'] == pytest.approx(2500.0)
    short = bench_figures.period_figures(ticks_ns([1000.0] * 10), PERIOD_NS)
    assert short['period_max_after_start_us'] is None  # a log shorter than the start


def test_the_docs_table_is_replaced_between_its_markers_and_nowhere_else():
    """The bench's --docs: the one current table of docs/performance.md, regenerated in place."""
    from actuator_bench.bench_report import DOCS_BEGIN, DOCS_END, docs_block, replace_docs_table

    text = f'# Performance\n\nmethod\n\n{DOCS_BEGIN}\nold table\n{DOCS_END}\n\nafter\n'
    env = {'cpus': 2, 'kernel': '6.1', 'load_avg_1_5_15': [0.25, 0.5, 0.5]}
    block = docs_block('python -m actuator_bench.bench --docs d.md', 'bench: x', 'T', env, env)
    new = replace_docs_table(text, block)
    assert new == (
        f'# Performance\n\nmethod\n\n{DOCS_BEGIN}\nRegenerated by `python -m actuator_bench.bench'
        ' --docs d.md` (bench: x; 2 CPUs, kernel 6.1, load average 0.25 at the start, 0.25 at '
        f'the end).\n\n```\nT\n```\n{DOCS_END}\n\nafter\n'
    )
    assert replace_docs_table(new, block) == new  # again: the same page
    with pytest.raises(ValueError, match='no <!-- bench-table:begin -->'):
        replace_docs_table('# no markers\n', block)
    docs = Path(__file__).resolve().parents[1] / 'docs' / 'performance.md'
    assert DOCS_BEGIN in docs.read_text() and DOCS_END in docs.read_text()
