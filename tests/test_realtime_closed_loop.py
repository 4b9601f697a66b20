# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The closed loop across processes in real time (SCHED_FIFO where the host grants it).

The paper's fast deep-sea run stays stable, and the controller on a 1 kHz timer closes the loop
with the newest measurement. Sim time against the offline core: tests/test_closed_loop_nodes.py.
"""

import json
import re

import numpy as np
import pytest

from actuator_bringup.supervisor import process_log
from actuator_controller.ppf import PrescribedPerformance
from actuator_core import limits
from actuator_core.status import CONTROLLED, Status
from host_probe import fifo_granted, skip_or_fail

#: The paper's initial envelope half-width rho0 [rad] (Table 4): the error of the whole run,
#: its start included, stays inside it.
RHO0_RAD = PrescribedPerformance().rho0_rad
#: docs/concepts/architecture.md#what-clocks-the-controller: the real-time fast deep-sea run
#: tracks with a max steady error of 7.3e-4 rad (6 s, SCHED_FIFO 50, either trigger).
DOCUMENTED_REALTIME_ERROR_RAD = 7.3e-4
#: Tracking judged from 1 s on (the start's transient over): max |e| within 3x the documented
#: figure (the offline core's own max over [1, 10) s is 9.7e-4 rad, 1.3x).
TRACKING_FROM_S = 1.0
TRACKING_MAX_RAD = 3 * DOCUMENTED_REALTIME_ERROR_RAD
#: One sample period [ns].
PERIOD_NS = round(limits.SAMPLE_TIME_S * 1e9)
#: Share of the answers that may take the controller more than a period to compute.
SLOW_ANSWERS_MAX_SHARE = 0.01
#: A stall answer (stale input, resync) lasts the stall plus the resync policy's 50 samples of
#: 0 A and brake: longer than this is no calm recovery (the worst seen here: 47 samples).
STALL_EPISODE_MAX = 120


def _lag_report(result) -> str:
    """Where a measurement's age comes from, for a failure message.

    The plant's publish lag (its wall clock at publish minus the stamp on its monotonic grid) and
    the controller's sensor-to-command age, p50 and p99 [ms] over each quarter of the run: a
    constant shift in both is the wall clock stepped against the monotonic one (the stamps'
    grid is monotonic from a wall-clock origin), a growth in the controller's alone a backlog.
    """
    lines = []
    plant_file = result.run_dir / 'plant_samples.npz'
    sources = [('controller age', result.timing_log, 'latency_ns', None)]
    if plant_file.is_file():
        sources.insert(0, ('plant publish lag', plant_file, 'published_wall_ns', 'stamp_ns'))
    for name, path, key, minus in sources:
        log = np.load(path)
        lag_ms = (log[key] - (log[minus] if minus else 0)) / 1e6
        quarters = np.array_split(lag_ms[np.isfinite(lag_ms)], 4)
        figures = (f'{np.median(q):.2f}/{np.percentile(q, 99):.2f}' for q in quarters if q.size)
        lines.append(f'{name} p50/p99 [ms] by quarter: ' + ', '.join(figures))
    return '; '.join(lines)


def _max_error_from(run, controlled: np.ndarray, start_s: float) -> float:
    """Max |e| [rad] of the controlled samples from ``start_s`` on (inf when there are none)."""
    window = controlled & (run.t >= start_s)
    return float(np.max(np.abs(run.error[window]))) if window.any() else np.inf


def _episode_lengths(flags: np.ndarray) -> np.ndarray:
    """Lengths of the runs of True in ``flags``, in samples."""
    edges = np.diff(np.concatenate(([0], flags.astype(np.int8), [0])))
    return np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)


def _require_fifo(logs: dict) -> None:
    """Skip on a machine that refuses SCHED_FIFO; fail when it grants it and a node lacks it."""
    if not fifo_granted():
        pytest.skip(
            'this machine refuses SCHED_FIFO: real-time stability is claimed only under it'
        )
    lacking = [key for key, text in logs.items() if 'running under SCHED_FIFO' not in text]
    assert not lacking, f'the machine grants SCHED_FIFO but {lacking} did not run under it'


@pytest.mark.realtime
def test_realtime_loop_stays_stable_for_the_whole_fast_deep_sea_run(isolated, host_window):
    """The paper's 10 s fast deep-sea run, PP-NFTSMC-ESO, in real time.

    The loop closes and, under SCHED_FIFO, stays stable.
    """
    from actuator_analysis.analyze import analyze_run, load_run
    from actuator_bringup.main import timing_figures
    from actuator_bringup.runner import run_closed_loop

    result = run_closed_loop(
        'case2_pp_nftsmc_eso',
        'realtime',
        None,
        record=True,
        bag_root=isolated / 'bags',
        results_root=isolated / 'runs',
        quiet=True,
        thread_priority=50,
    )
    assert all(code == 0 for code in result.exit_codes.values()), result.exit_codes
    timing = timing_figures(result)
    assert timing['updates'] > 500  # the loop closed
    # a command answers its sample within that sample's period (0.37 ms here)
    assert 100.0 < timing['latency_us']['p50'] < 1e6 * limits.SAMPLE_TIME_S, _lag_report(result)
    run = load_run(result.bag, quiet=True)
    assert np.all(np.isfinite(run.current)) and np.max(np.abs(run.current)) <= 20.0 + 1e-9
    assert analyze_run(run).metrics.samples > 0  # recorded and readable
    plant = np.load(result.run_dir / 'plant_samples.npz')
    assert plant['stamp_ns'].size > 9000 and np.all(np.diff(plant['stamp_ns']) % 1_000_000 == 0)
    # 18-40 % of a core and 72-82 MB per node here; twice and 1.5 times that are faults
    assert all(v is not None and 5.0 < v < 80.0 for v in result.cpu_percent.values()), (
        result.cpu_percent
    )
    assert all(40.0 < v < 125.0 for v in result.peak_rss_mb.values()), result.peak_rss_mb
    logs = {key: process_log(result.run_dir, key) for key in ('plant', 'eso', 'controller')}
    _require_fifo(logs)
    # Stable for the whole run: never latched (|e| under the following-error limit), the error
    # stays inside the paper's initial envelope (rho0 = 0.25 rad; 9 runs here: at most 4.6e-2
    # rad), and the observer integrated the commanded current on time or by repair for nearly
    # every sample.
    assert 'safe stop latched' not in logs['controller']
    controlled = np.isin(run.status, CONTROLLED)  # safe stops carry no error (NaN)
    assert controlled.any(), 'no sample controlled'
    max_error = np.max(np.abs(run.error[controlled]))
    assert max_error < limits.FOLLOWING_ERROR_LIMIT_RAD, max_error
    tracking = _max_error_from(run, controlled, TRACKING_FROM_S)
    eso = json.loads((result.run_dir / 'eso_stats.json').read_text())
    paired = (eso['exact_pairs'] + eso['repaired_pairs']) / eso['steps']
    timing_log = np.load(result.timing_log)
    latency_ns = timing_log['latency_ns']
    late = int(np.sum(latency_ns > PERIOD_NS))
    # The lateness count the controller reports (its timing line, /diagnostics and
    # controller/state carry it) is its own log's, whatever the host did.
    reported = re.search(r'\btiming .*\blate=(\d+)', logs['controller'])
    assert reported and int(reported[1]) == late, (reported and reported[0], late)
    # The controller's own time per answer, on its SCHED_FIFO thread: a host of any speed keeps
    # it under a period (here 4 answers in 9809 over, 5 % with every 20th answer 2 ms late), so
    # only the host's stalls excuse it, not a slow host.
    slow_answers = int(np.sum(timing_log['compute_ns'] > PERIOD_NS))
    if slow_answers > SLOW_ANSWERS_MAX_SHARE * latency_ns.size:
        skip_or_fail(
            host_window,
            f'{slow_answers} of {latency_ns.size} answers took the controller more than a '
            f'period ({late} commands after the next sample)',
            samples=slow_answers,
            slow_host_excuses=False,
        )
    outside = (
        paired < 0.9,
        controlled.mean() <= 0.9,
        max_error >= RHO0_RAD,
        tracking >= TRACKING_MAX_RAD,
    )
    if any(outside):
        # A stall of the host past the command timeout is a resync (50 samples of 0 A and brake
        # by the policy), and a command later than the next sample reaches the observer after
        # it stepped (the pairing itself is tests/test_pairing_boundaries.py's, sample by
        # sample): the host may explain the late and uncontrolled samples, a quiet host not.
        skip_or_fail(
            host_window,
            f'{late} commands after the next sample, the observer paired {paired:.0%} on time '
            f'or by repair, {controlled.mean():.0%} of the samples controlled; max |e| '
            f'{max_error:.2e} rad, from {TRACKING_FROM_S:g} s {tracking:.2e} rad, no latch',
            samples=late + int(np.sum(~controlled)),
        )
    assert max_error < RHO0_RAD, max_error
    assert tracking < TRACKING_MAX_RAD, (
        f'max |e| from {TRACKING_FROM_S:g} s {tracking:.2e} rad '
        f'(documented {DOCUMENTED_REALTIME_ERROR_RAD}); {late:.1%} of the commands late, '
        f'{controlled.mean():.1%} controlled'
    )
    assert controlled.mean() > 0.9, f'{controlled.mean():.1%} controlled, {late:.1%} late'
    assert paired >= 0.9, (eso, f'{late:.1%} of commands later than one period')


@pytest.mark.realtime
def test_controller_on_a_1_khz_timer_closes_the_loop_with_the_newest_measurement(
    isolated, host_window
):
    """Tick on a timer (trigger:=timer) with the newest measurement: the loop closes and tracks."""
    from actuator_analysis.analyze import load_run
    from actuator_bringup.runner import run_closed_loop

    duration_s = 6.0
    result = run_closed_loop(
        'case2_pp_nftsmc_eso',
        'realtime',
        duration_s,
        bag_root=isolated / 'bags',
        results_root=isolated / 'runs',
        quiet=True,
        thread_priority=50,
        extra_params=['-p', 'actuator_controller:trigger:=timer'],
    )
    assert all(code == 0 for code in result.exit_codes.values()), result.exit_codes
    log = np.load(result.timing_log)
    assert log['stamp_ns'].size > 0 and np.all(np.diff(log['stamp_ns']) > 0)  # one per sample
    age_us = log['latency_ns'] / 1e3  # measurement age when its command went out
    # up to a period on top of the hop: 1.1 ms here
    assert 100.0 < np.percentile(age_us, 50) < 2000.0, _lag_report(result)
    run = load_run(result.bag, quiet=True)
    controlled = np.isin(run.status, CONTROLLED)  # the law ran: OK or RECOVERING
    # Whatever the host: never latched (|e| under the following-error limit whenever the law ran),
    # and every sample the law did not run is the answer to a stall (stale input or resync), over
    # in a calm episode: a stall of the host is no chase and no latch.
    assert 'safe stop latched' not in process_log(result.run_dir, 'controller')
    assert controlled.any()
    max_error = np.max(np.abs(run.error[controlled]))
    assert max_error < limits.FOLLOWING_ERROR_LIMIT_RAD, max_error
    stall_answers = (Status.STALE_MEASUREMENT, Status.STALE_ESTIMATE, Status.RESYNC)
    started = np.flatnonzero(controlled)[0]  # WAITING before the first estimate
    ended = np.flatnonzero(controlled)[-1] + 1  # stale after the plant stopped at the end
    after = run.status[started:ended]
    assert np.all(np.isin(after, CONTROLLED + stall_answers)), np.unique(after)
    episodes = _episode_lengths(~np.isin(after, CONTROLLED))
    assert episodes.size == 0 or episodes.max() <= STALL_EPISODE_MAX, episodes.max()
    tracking = _max_error_from(run, controlled, TRACKING_FROM_S)
    outside = controlled.mean() <= 0.9 or max_error >= RHO0_RAD or tracking >= TRACKING_MAX_RAD
    if outside:
        skip_or_fail(
            host_window,
            f'{episodes.size} stall answers in {duration_s:g} s: {controlled.mean():.0%} of the '
            f'samples controlled, the longest answer {episodes.max() if episodes.size else 0} '
            f'samples; max |e| {max_error:.2e} rad, from {TRACKING_FROM_S:g} s '
            f'{tracking:.2e} rad, no latch',
            samples=int(np.sum(~np.isin(after, CONTROLLED))),
        )
    assert max_error < RHO0_RAD, max_error
    assert tracking < TRACKING_MAX_RAD, (
        f'max |e| from {TRACKING_FROM_S:g} s {tracking:.2e} rad '
        f'(documented {DOCUMENTED_REALTIME_ERROR_RAD}); {episodes.size} stall episodes, '
        f'{controlled.mean():.1%} controlled'
    )
    assert controlled.mean() > 0.9, (controlled.mean(), episodes)
    # the law ran for most of the 6000 samples (a run the host stalled into resyncs ends above)
    assert log['stamp_ns'].size > 4000, log['stamp_ns'].size


@pytest.mark.realtime
def test_wall_clock_steps_in_every_node_of_a_running_loop_leave_it_tracking(
    isolated, monkeypatch, host_window
):
    """The wall clock of the joint, the observer and the controller steps at one instant.

    -5 ms, +5 ms, -1 s, +1 s, a second apart (ACTUATOR_WALL_CLOCK_STEPS in every process): the
    stamps count monotonic periods and each receiver judges them against its own stamp time, so
    no measurement is refused as ahead, no time base jumps, and the loop tracks through it.
    """
    import time

    from actuator_analysis.analyze import load_run
    from actuator_bringup.runner import run_closed_loop
    from actuator_core.clock import STEPS_ENV

    at = time.monotonic() + 4.0  # the loop starts in about 2 s
    steps = [(at, -5e-3), (at + 1.0, 5e-3), (at + 2.0, -1.0), (at + 3.0, 1.0)]
    monkeypatch.setenv(STEPS_ENV, ','.join(f'{t:.3f}:{s:g}' for t, s in steps))
    result = run_closed_loop(
        'case2_pp_nftsmc_eso',
        'realtime',
        8.0,
        bag_root=isolated / 'bags',
        results_root=isolated / 'runs',
        quiet=True,
        thread_priority=50,
    )
    assert all(code == 0 for code in result.exit_codes.values()), result.exit_codes
    logs = {key: process_log(result.run_dir, key) for key in ('plant', 'eso', 'controller')}
    for key in ('eso', 'controller'):
        assert 'beyond the sample clock' not in logs[key], logs[key][-2000:]
        assert 'time base jumped' not in logs[key] and 'a jump of the time base' not in logs[key]
    plant = np.load(result.run_dir / 'plant_samples.npz')
    assert np.all(np.diff(plant['stamp_ns']) % 1_000_000 == 0)  # no stamp moved off the grid
    run = load_run(result.bag, quiet=True)
    controlled = np.isin(run.status, CONTROLLED)
    assert 'safe stop latched' not in logs['controller']
    tracking = _max_error_from(run, controlled, TRACKING_FROM_S)
    if tracking >= TRACKING_MAX_RAD or controlled.mean() <= 0.9:
        skip_or_fail(
            host_window,
            f'max |e| from {TRACKING_FROM_S:g} s {tracking:.2e} rad, {controlled.mean():.0%} '
            'controlled through the wall-clock steps',
            samples=int(np.sum(~controlled)),
        )
