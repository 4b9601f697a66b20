# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Per-goal figures of a commanded run (actuator_analysis.goals), on a synthetic run."""

from pathlib import Path

import numpy as np
import pytest

from actuator_analysis.analyze import RunData
from actuator_analysis.goals import GoalEventRow, format_goals, goal_reports
from actuator_core.status import Status

MS = 1_000_000
T0 = 1_000 * MS


def _event(ms, goal_id, kind, code=0, why='', end_ms=0, action=True, points=0):
    return GoalEventRow(
        T0 + ms * MS, goal_id, action, kind, code, why, 0, T0 + end_ms * MS, points, 'positions'
    )


def _run(error, saturated=(), status=None, events=()):
    n = len(error)
    run = RunData(
        name='synthetic',
        path=Path('synthetic'),
        controller='pp_nftsmc_eso',
        t0_ns=T0,
        t=np.arange(n) * 1e-3,
        reference=np.zeros(n),
        measured=np.asarray(error, dtype=float),
        error=np.asarray(error, dtype=float),
        lower=np.full(n, -0.05),
        upper=np.full(n, 0.05),
        current=np.zeros(n),
        saturated=np.isin(np.arange(n), list(saturated)),
        status=np.full(n, int(Status.OK)) if status is None else np.asarray(status),
    )
    run.goal_events = list(events)
    return run


def test_a_goal_that_succeeded_reports_its_path_end_settling_and_limit_samples():
    error = np.zeros(1000)
    error[100:300] = 2e-3  # along the path
    error[299] = 4e-3  # its worst
    error[300:340] = 1.5e-3  # after it was due: outside the band until 340 ms
    events = [
        _event(50, 'a', 'accepted', points=3),
        _event(100, 'a', 'started', end_ms=300),
        _event(300, 'a', 'succeeded', why='Goal successfully reached!'),
    ]
    (report,) = goal_reports(_run(error, saturated=(120, 121, 700), events=events))
    assert (report.result, report.points, report.interpolation) == ('succeeded', 3, 'positions')
    assert (report.started_s, report.due_s, report.ended_s) == pytest.approx((0.1, 0.3, 0.3))
    assert report.max_path_error_rad == pytest.approx(4e-3)
    assert report.final_error_rad == pytest.approx(1.5e-3)
    assert report.settling_time_s == pytest.approx(0.040)
    assert report.saturated_samples == 3  # its window runs to the end of the run


def test_a_goal_window_ends_where_the_next_goal_starts_and_a_cancel_settles_from_it():
    error = np.zeros(1000)
    error[400:420] = 3e-3  # after the cancel at 400 ms
    error[500:520] = 9e-3  # the second goal's: not the first's
    events = [
        _event(0, 'a', 'accepted'),
        _event(100, 'a', 'started', end_ms=900),
        _event(400, 'a', 'canceled'),
        _event(450, 'b', 'accepted'),
        _event(500, 'b', 'started', end_ms=800),
    ]
    first, second = goal_reports(_run(error, saturated=(510,), events=events))
    assert first.result == 'canceled'
    assert first.max_path_error_rad == pytest.approx(3e-3)  # the path ends at the cancel
    assert first.final_error_rad == pytest.approx(3e-3)
    assert first.settling_time_s == pytest.approx(0.020)
    assert first.saturated_samples == 0  # 510 ms is in the second goal's window
    assert (second.result, second.saturated_samples) == ('running', 1)
    assert second.max_path_error_rad == pytest.approx(9e-3)


def test_a_goal_that_never_settles_says_so_and_refusals_keep_their_reason():
    error = np.full(600, 2e-3)
    events = [
        _event(10, 'refused-1', 'refused', why='Empty trajectory received.'),
        _event(20, 'c', 'accepted'),
        _event(100, 'c', 'started', end_ms=200),
        _event(
            250, 'c', 'aborted', -5, 'Aborted due to goal_time_tolerance exceeding by 0.050000'
        ),
    ]
    refused, aborted = goal_reports(_run(error, events=events))
    assert (refused.result, refused.error_string) == ('refused', 'Empty trajectory received.')
    assert refused.started_s is None
    assert aborted.result == 'aborted' and aborted.settling_time_s is None
    table = format_goals([refused, aborted])
    assert 'Empty trajectory received.' in table and 'aborted' in table


def test_samples_the_law_did_not_control_are_left_out_of_the_errors():
    error = np.zeros(400)
    error[150:160] = np.nan  # a resync: no error
    status = np.full(400, int(Status.OK))
    status[150:160] = int(Status.RESYNC)
    events = [_event(100, 'a', 'started', end_ms=300)]
    (report,) = goal_reports(_run(error, status=status, events=events))
    assert report.max_path_error_rad == 0.0
