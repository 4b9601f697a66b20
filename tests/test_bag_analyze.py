# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""bag_analyze computes the run figures from bags offline and draws the figures.

It rejects bad input cleanly.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from actuator_analysis.analyze import analyze_run, load_run
from actuator_analysis.analyze_table import format_table
from actuator_analysis.cli import main
from actuator_bag.bag_format import mcap_name
from bag_helpers import REPO, synthetic_run, write_run_bag

CONTROLLERS = ('pp_nftsmc_eso', 'nftsmc_eso', 'smc_eso', 'pi')


def _rms(x: np.ndarray) -> float:
    """Root mean square."""
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.fixture(scope='module')
def case2(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, object]]:
    """Four synthetic bags, one per controller.

    Only the PP one has an envelope; pi misses two samples.
    """
    root = tmp_path_factory.mktemp('case2')
    bags = {}
    for seed, name in enumerate(CONTROLLERS):
        run = synthetic_run(
            duration_s=6.0,
            seed=seed,
            envelope=name == 'pp_nftsmc_eso',
            drop_joint=(2000, 3000) if name == 'pi' else (),
        )
        bags[name] = (write_run_bag(root / name, run, controller=name), run)
    return bags


@pytest.mark.slow
def test_figures_match_the_recorded_arrays(case2) -> None:
    """Every figure equals what the arrays the bag was written from give."""
    path, run = case2['pp_nftsmc_eso']
    report = analyze_run(load_run(path, quiet=True), steady_state_start_s=5.0)
    m = report.metrics
    steady = run.t >= 5.0
    assert report.run.controller == 'pp_nftsmc_eso'
    assert m.samples == run.t.size
    assert m.steady_window_s[0] == 5.0 and m.steady_window_s[1] == pytest.approx(run.t[-1])
    assert m.max_steady_error_rad == pytest.approx(np.max(np.abs(run.error[steady])))
    assert m.rms_steady_error_rad == pytest.approx(_rms(run.error[steady]))
    assert m.rms_error_rad == pytest.approx(_rms(run.error))
    assert m.max_abs_current_a == pytest.approx(np.max(np.abs(run.current)))
    assert m.rms_current_a == pytest.approx(_rms(run.current))
    assert m.bounds_kept and m.bounds_violations == 0
    assert m.rms_velocity_estimate_error_rad_s == pytest.approx(
        _rms(run.est_velocity - run.truth_velocity)
    )
    assert m.rms_disturbance_estimate_error_rad_s2 == pytest.approx(
        _rms(run.est_disturbance - run.truth_disturbance)
    )
    latency = run.latency_ns * 1e-9
    assert report.timing['command_latency']['p50_s'] == pytest.approx(np.percentile(latency, 50))
    assert report.timing['command_latency']['max_s'] == pytest.approx(latency.max())
    assert report.timing['sample_period']['p50_s'] == pytest.approx(1e-3)
    assert report.missed_samples == 0
    assert report.as_dict()['status_not_ok_fraction'] == 0.0


@pytest.mark.slow
def test_gaps_violations_and_missing_envelope(case2, tmp_path: Path) -> None:
    """Dropped samples are counted; a bound violation is found.

    No envelope means no compliance figure.
    """
    report = analyze_run(load_run(case2['pi'][0], quiet=True))
    assert report.missed_samples == 2
    assert report.timing['sample_period']['max_s'] == pytest.approx(2e-3)
    assert not report.run.has_envelope and report.metrics.bounds_violations == 0
    run = synthetic_run(duration_s=1.0, violate_at=321)
    bad = analyze_run(load_run(write_run_bag(tmp_path / 'violated', run), quiet=True))
    assert not bad.metrics.bounds_kept and bad.metrics.bounds_violations == 1


@pytest.mark.slow
def test_without_truth_estimation_is_not_reported(tmp_path: Path) -> None:
    """A hardware bag (no plant/truth) is analysed.

    Estimation figures are left out, not invented.
    """
    path = write_run_bag(
        tmp_path / 'hw',
        synthetic_run(duration_s=1.0),
        topics=('joint', 'command', 'estimate', 'state'),
    )
    report = analyze_run(load_run(path, quiet=True))
    assert report.metrics.rms_velocity_estimate_error_rad_s is None
    assert report.run.velocity_error is None
    assert report.as_dict()['observer_input'] is None
    assert 'n/a (no truth)' in format_table([report])


@pytest.mark.slow
def test_the_samples_whose_observer_input_was_not_the_current_held(tmp_path: Path) -> None:
    """eso/estimate's input current against plant/truth's held current, sample by sample."""
    run = synthetic_run(duration_s=1.0)
    same = analyze_run(load_run(write_run_bag(tmp_path / 'same', run), quiet=True))
    assert same.as_dict()['observer_input'] == {
        'samples': run.t.size,
        'differing': 0,
        'max_abs_a': 0.0,
    }
    late = run.current.copy()
    late[[100, 101, 500]] += (2.5, -0.5, 40.0)  # commands that reached the observer only
    run.observer_input = late
    report = analyze_run(load_run(write_run_bag(tmp_path / 'late', run), quiet=True))
    figures = report.as_dict()['observer_input']
    assert figures['differing'] == 3 and figures['max_abs_a'] == pytest.approx(40.0)
    assert '3 of 1000 samples differ, max 40 A' in format_table([report])


@pytest.mark.slow
def test_cli_case2_table_json_and_figures(
    case2, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Four bags: one table column each, JSON with the same figures, the five PNG figures."""
    bags = [str(case2[name][0]) for name in CONTROLLERS]
    out = tmp_path / 'fig'
    code = main(
        [
            *bags,
            '--out',
            str(out),
            '--json',
            str(tmp_path / 'r.json'),
            '--steady-start',
            '4.5',
            '--msg-path',
            str(REPO / 'src'),
        ]
    )
    captured = capsys.readouterr()
    assert code == 0, captured.err
    lines = captured.out.splitlines()
    assert lines[0].split() == ['bag', *CONTROLLERS]
    assert any(line.startswith('steady window') and '4.5-' in line for line in lines)
    assert any(
        line.startswith('PPF bounds') and 'kept' in line and 'n/a (no envelope)' in line
        for line in lines
    )
    doc = json.loads((tmp_path / 'r.json').read_text())
    assert [d['controller'] for d in doc] == list(CONTROLLERS)
    assert doc[0]['metrics']['steady_window_s'][0] == 4.5
    for name in (
        'position',
        'tracking_error',
        'velocity_estimate',
        'disturbance_estimate',
        'control_input',
    ):
        png = out / f'{name}.png'
        assert png.is_file() and png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert 'bag_analyze pp_nftsmc_eso: 100 %' in captured.err


def _cli(*args: str) -> subprocess.CompletedProcess:
    """Run bag_analyze as a separate process."""
    return subprocess.run(
        [sys.executable, '-m', 'actuator_analysis.cli', '-q', *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    'case', ['missing', 'not_a_bag', 'text_file', 'truncated', 'no_topics', 'interrupted']
)
def test_bad_input_is_one_line_error(case2, tmp_path: Path, case: str) -> None:
    """Bad input: one line naming the problem, exit code 1, never a traceback."""
    target = tmp_path / 'bag'
    expect = {
        'missing': 'does not exist',
        'not_a_bag': 'not a rosbag2 bag',
        'text_file': 'not a bag',
        'truncated': 'truncated',
        'no_topics': 'no actuator_msgs/msg/ControllerState topic',
        'interrupted': 'bag_repair',
    }[case]
    if case == 'not_a_bag':
        target.mkdir()
        (target / 'notes.txt').write_text('x')
    elif case == 'text_file':
        target = tmp_path / 'notes.txt'
        target.write_text('x')
    elif case == 'truncated':
        write_run_bag(target, synthetic_run(duration_s=0.3))
        mcap = target / mcap_name(target)
        with open(mcap, 'r+b') as bio:
            bio.truncate(mcap.stat().st_size // 2)
    elif case == 'no_topics':
        write_run_bag(target, synthetic_run(duration_s=0.3), topics=('joint', 'command'))
    elif case == 'interrupted':
        write_run_bag(target, synthetic_run(duration_s=0.3))
        (target / 'metadata.yaml').unlink()
    proc = _cli(str(case2['pi'][0]), str(target))
    assert proc.returncode == 1
    assert 'Traceback' not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert (
        len(lines) == 1 and lines[0].startswith('bag_analyze: error: ') and expect in lines[0]
    ), proc.stderr
    assert str(target) in lines[0]


def test_help() -> None:
    """--help answers and exits 0."""
    with pytest.raises(SystemExit) as exc:
        main(['--help'])
    assert exc.value.code == 0


def test_a_component_with_no_report_inside_the_run_is_never_said_ok() -> None:
    from actuator_analysis.analyze import summarize_diagnostics
    from actuator_analysis.analyze_table import _diagnostics

    reports = [
        (5, 'actuator_plant', 0, ''),  # before the run
        (50, 'actuator_plant', 0, ''),  # after it
        (20, 'actuator_eso', 0, ''),
        (30, 'actuator_eso', 1, 'late'),
    ]
    summary = summarize_diagnostics(reports, (10, 40))
    assert summary['actuator_plant']['worst'] is None
    assert summary['actuator_eso']['worst'] == 'WARN'

    class Run:
        diagnostics = summary

    class Report:
        run = Run()

    assert _diagnostics(Report()).splitlines() == [
        'actuator_eso WARN (OK 1 WARN 1): late',
        'actuator_plant none stamped inside the run (2 outside it)',
    ]


@pytest.mark.slow
def test_a_run_shorter_than_the_steady_window_gets_no_empty_panel(tmp_path: Path, monkeypatch):
    from matplotlib.figure import Figure

    from actuator_analysis.figures import STEADY_STATE_START_S, draw_figures

    panels: dict[str, int] = {}
    save = Figure.savefig

    def counting(fig, path, *args, **kwargs):
        panels[Path(path).name] = len(fig.axes)
        return save(fig, path, *args, **kwargs)

    monkeypatch.setattr(Figure, 'savefig', counting)
    for duration in (STEADY_STATE_START_S - 1.0, STEADY_STATE_START_S + 1.0):
        bag = write_run_bag(tmp_path / f'run{duration:g}', synthetic_run(duration_s=duration))
        draw_figures([load_run(bag, quiet=True)], tmp_path / f'fig{duration:g}')
        assert panels['tracking_error.png'] == (1 if duration < STEADY_STATE_START_S else 2)
