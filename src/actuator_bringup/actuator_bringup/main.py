# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The main job (``make main``): the paper's hardest case across three processes, in both modes.

Fast trajectory, deep sea (10 MPa, 2 degC), PP-NFTSMC-ESO: plant, ESO and controller run
as separate processes, recorded to bags/ by the recorder, first in deterministic sim time
(checked sample by sample against the offline core), then in real time. Each bag is then
analysed (metrics and the paper's five figures) and a short report is printed. Beside it, a
commanded run (actuator_bringup.commanded): the same loop holding still until a scripted client
sends a multi-point goal, replaces it mid-motion and cancels a third, reported per goal (and in
sim time replayed offline, sample by sample).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from actuator_analysis.analyze import analyze_run, load_run
from actuator_analysis.analyze_table import format_table
from actuator_analysis.figures import draw_figures
from actuator_analysis.goals import format_goals, goal_reports
from actuator_bringup.commanded import COMMANDED_DURATION_S, replay_offline, scripted_run
from actuator_bringup.runner import RunResult, run_closed_loop
from actuator_core import limits
from actuator_core.stats import missed_samples, percentiles
from actuator_core.timing import period_ns
from actuator_sim.loop import ClosedLoop
from actuator_sim.offline import trace_metrics
from actuator_sim.params_yaml import all_scenarios
from actuator_sim.scenarios import PAPER_SCENARIO

SCENARIO = PAPER_SCENARIO


def timing_figures(result: RunResult) -> dict:
    """Read the controller update period and sensor-to-command latency.

    From the controller's timing log.
    """
    if not result.timing_log.is_file():
        return {}
    log = np.load(result.timing_log)
    period_us = np.diff(log['received_wall_ns']) / 1e3

    def table(values, **kw) -> dict:
        return {k.rsplit('_', 1)[1]: v for k, v in percentiles(values, 'x', **kw).items()}

    figures: dict[str, object] = {'updates': int(log['stamp_ns'].size)}
    if period_us.size:
        figures['period_us'] = table(period_us, mean=True)
    if result.mode == 'realtime' and log['latency_ns'].size:
        figures['latency_us'] = table(log['latency_ns'] / 1e3)
    figures['missed_samples'] = missed_samples(log['stamp_ns'], period_ns(limits.SAMPLE_TIME_S))
    return figures


def compare_with_offline(run, trace) -> dict:
    """Sample-by-sample difference between a recorded run and the offline core (by stamp index).

    Over the samples both controlled (a sample the law did not run carries no error: NaN);
    identical only when every recorded sample is the offline one, NaNs in the same places.
    """
    index = np.rint(run.t * 1000.0).astype(int)
    ok = index < trace['error_rad'].size
    error, offline_error = run.error[ok], trace['error_rad'][index[ok]]
    current, offline_current = run.current[ok], trace['current_a'][index[ok]]
    both = np.isfinite(error) & np.isfinite(offline_error)
    de = np.abs(error[both] - offline_error[both])
    du = np.abs(current[both] - offline_current[both])
    same_nan = np.array_equal(np.isnan(error), np.isnan(offline_error))
    return {
        'samples_compared': int(ok.sum()),
        'samples_controlled_in_both': int(both.sum()),
        'max_abs_error_diff_rad': float(de.max()) if de.size else None,
        'max_abs_current_diff_a': float(du.max()) if du.size else None,
        'identical': bool(de.size and same_nan and not de.any() and not du.any()),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Run both modes, analyse the bags, print the report."""
    parser = argparse.ArgumentParser(prog='main', description=__doc__.splitlines()[0])
    parser.add_argument(
        '--duration', type=float, default=10.0, help='run length [s] of each mode (default 10)'
    )
    parser.add_argument(
        '--modes', nargs='+', choices=('sim', 'realtime'), default=['sim', 'realtime']
    )
    parser.add_argument(
        '--out', type=Path, default=Path('results/main'), help='figures and report (JSON)'
    )
    args = parser.parse_args(argv)
    if not 5.0 < args.duration <= 600.0:
        parser.error('--duration must be in (5, 600] s (the steady-state window starts at 5 s)')
    scenario = all_scenarios()[SCENARIO]
    scenario.duration_s = args.duration
    print(
        f'== {SCENARIO}: fast trajectory, deep sea (10 MPa, 2 degC), PP-NFTSMC-ESO, '
        f'{args.duration:g} s at 1 kHz',
        flush=True,
    )
    offline = ClosedLoop(scenario).run()
    offline_metrics = trace_metrics(offline)
    report: dict = {'scenario': SCENARIO, 'offline': offline_metrics.as_dict(), 'runs': {}}
    runs = []
    for mode in args.modes:
        print(
            f'\n== {mode} mode: plant, ESO, controller and recorder as separate processes',
            flush=True,
        )
        # realtime: SCHED_FIFO 50 for plant, ESO and controller (ros2_control's default thread
        # priority); where the machine refuses, the nodes say so and run with normal scheduling.
        result = run_closed_loop(
            SCENARIO, mode, args.duration, thread_priority=50 if mode == 'realtime' else 0
        )
        if any(code != 0 for code in result.exit_codes.values()):
            print(
                f'main: a node exited with an error: {result.exit_codes}; logs in '
                f'{result.run_dir}',
                file=sys.stderr,
            )
            return 1
        assert result.bag is not None  # a recorded run
        run = load_run(result.bag, quiet=True)
        runs.append(run)
        analysis = analyze_run(run)
        figures = draw_figures([run], args.out / result.name)
        entry = {
            'bag': str(result.bag),
            'metrics': analysis.metrics.as_dict(),
            'timing': timing_figures(result),
            'cpu_percent_of_one_core': result.cpu_percent,
            'peak_rss_mb': result.peak_rss_mb,
            'figures': [str(f) for f in figures],
            'offline_comparison': compare_with_offline(run, offline),
        }
        report['runs'][mode] = entry
        print_run(mode, entry, offline_metrics.max_steady_error_rad)
    print('\n== bags compared (bag_analyze)')
    print(format_table([analyze_run(r) for r in runs]))
    report['commanded'] = {mode: commanded_run(mode, args.out) for mode in args.modes}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'report.json').write_text(json.dumps(report, indent=1, default=str))
    print(f'\nreport: {args.out / "report.json"}')
    return 0


def commanded_run(mode: str, out: Path) -> dict:
    """Run the commanded run in ``mode``: goals as a ROS user sends them, reported per goal."""
    print(
        f'\n== commanded run, {mode} mode: hold_pp_nftsmc_eso holds still; a scripted client '
        'sends a multi-point goal, replaces it mid-motion and cancels a third',
        flush=True,
    )
    result, client = scripted_run(Path('bags'), Path('results/runs'), mode, COMMANDED_DURATION_S)
    entry: dict = {'bag': str(result.bag), 'exit_codes': result.exit_codes}
    if client.error or any(code != 0 for code in result.exit_codes.values()):
        print(f'  the run failed: {client.error or result.exit_codes}; logs in {result.run_dir}')
        return entry
    assert result.bag is not None  # a recorded run
    run = load_run(result.bag, quiet=True)
    goals = goal_reports(run)
    entry['goals'] = [g.as_dict() for g in goals]
    print(f'bag: {result.bag}\n{format_goals(goals)}')
    if mode == 'sim':
        replay = replay_offline(run, client, COMMANDED_DURATION_S)
        entry['offline_comparison'] = compare_with_offline(run, replay.trace)
        c = entry['offline_comparison']
        print(
            f'  vs the offline loop handed the same goals at the same samples: '
            f'{c["samples_compared"]} samples, '
            f'{"identical" if c["identical"] else "DIFFERENT"}'
        )
    figures = draw_figures([run], out / result.name)
    entry['figures'] = [str(f) for f in figures]
    print(f'  figures (desired and measured angle, error, current): {Path(figures[0]).parent}')
    return entry


def print_run(mode: str, entry: dict, offline_error: float) -> None:
    """Return the short report of one mode."""
    m, t, c = entry['metrics'], entry['timing'], entry['offline_comparison']
    print(f'bag: {entry["bag"]}')
    print(
        f'  max steady-state error '
        f'[{m["steady_window_s"][0]:g}, {m["steady_window_s"][1]:.3g}] s: '
        f'{m["max_steady_error_rad"]:.3e} rad '
        f'(offline core: {offline_error:.3e}, paper Table 6: 6.96e-04)'
    )
    print(
        f'  RMS error: {m["rms_error_rad"]:.3e} rad; max |u|: {m["max_abs_current_a"]:.2f} A; '
        f'PPF bounds {"kept" if m["bounds_kept"] else "VIOLATED"}; diverged: {m["diverged"]}'
    )
    if 'period_us' in t:
        p = t['period_us']
        print(
            f'  controller update period: mean {p["mean"]:.1f} us, p50 {p["p50"]:.1f} us, p99 '
            f'{p["p99"]:.1f} us, '
            f'max {p["max"]:.1f} us; missed samples {t["missed_samples"]}'
        )
    if 'latency_us' in t:
        lat = t['latency_us']
        print(
            f'  sensor-to-command latency: p50 {lat["p50"]:.0f} us, p99 {lat["p99"]:.0f} us, '
            f'max {lat["max"]:.0f} us'
        )
    if mode == 'sim':  # the lockstep runs the offline core's objects: bit for bit
        verdict = 'identical' if c['identical'] else 'DIFFERS: sim mode should equal it'
    else:  # real time: the host's timing differs from the grid's, so does the error
        verdict = 'real time, not expected identical'
    diff = c['max_abs_error_diff_rad']
    print(
        f'  vs offline core: {c["samples_compared"]} samples, max |de| '
        f'{"n/a" if diff is None else f"{diff:.3e} rad"} over the '
        f'{c["samples_controlled_in_both"]} controlled in both ({verdict})'
    )
    cpu = ', '.join(
        f'{k} {v:.0f} %' for k, v in entry['cpu_percent_of_one_core'].items() if v is not None
    )
    rss = ', '.join(f'{k} {v:.0f} MB' for k, v in entry['peak_rss_mb'].items())
    print(f'  CPU (of one core): {cpu}; peak RSS: {rss}')
    print(
        f'  figures: {", ".join(Path(f).name for f in entry["figures"])} in '
        f'{Path(entry["figures"][0]).parent}'
    )


if __name__ == '__main__':
    sys.exit(main())
