# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Per goal of a commanded run: what became of it and how the joint followed.

From controller/goal_events (actuator_msgs/GoalEvent) and controller/state. A goal's window
runs from the sample it started at to the next goal's start (or the run's end). Per goal:
its result and reason; max |e| along its path (from its start until its last point was due,
or until it ended if earlier); |e| at the sample it ended (or was due); its settling time
(after it was due, or ended, until |e| stays within GOAL_SETTLING_BAND_RAD to the end of its
window; None when it never does); and its samples at the current limit in its window. Errors
are taken over the samples the law controlled (status OK or RECOVERING). Refused trajectories
are listed with their reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple, Optional

import numpy as np

from actuator_core.limits import GOAL_SETTLING_BAND_RAD
from actuator_core.status import CONTROLLED
from actuator_core.timing import stamp_to_ns

#: GoalEvent.event values by name (EVENT_REFUSED = 0 ... EVENT_CANCELED = 5).
EVENT_NAMES = ('refused', 'accepted', 'started', 'succeeded', 'aborted', 'canceled')
#: The events that end a goal.
ENDS = ('succeeded', 'aborted', 'canceled')


class GoalEventRow(NamedTuple):
    """One actuator_msgs/GoalEvent as the analysis keeps it."""

    stamp_ns: int
    goal_id: str
    from_action: bool
    kind: str  #: one of EVENT_NAMES
    error_code: int
    error_string: str
    start_ns: int
    end_ns: int
    points: int
    interpolation: str


def goal_event_row(msg: Any) -> GoalEventRow:
    """Return the row of one decoded GoalEvent message."""
    event = int(msg.event)
    return GoalEventRow(
        stamp_to_ns(msg.header.stamp),
        str(msg.goal_id),
        bool(msg.from_action),
        EVENT_NAMES[event] if 0 <= event < len(EVENT_NAMES) else str(event),
        int(msg.error_code),
        str(msg.error_string),
        stamp_to_ns(msg.start),
        stamp_to_ns(msg.end),
        int(msg.points),
        str(msg.interpolation),
    )


@dataclass
class GoalReport:
    """One goal of a run (times in s from the run's start, errors in rad)."""

    goal_id: str
    from_action: bool
    result: str  #: succeeded, aborted, canceled, refused, or running (no end in the bag)
    error_string: str = ''
    points: int = 0
    interpolation: str = ''
    started_s: Optional[float] = None
    due_s: Optional[float] = None
    ended_s: Optional[float] = None
    max_path_error_rad: Optional[float] = None
    final_error_rad: Optional[float] = None
    settling_time_s: Optional[float] = None
    saturated_samples: int = 0

    def as_dict(self) -> dict:
        """Plain-dict form for JSON output."""
        return dict(vars(self))


def goal_reports(run, band_rad: float = GOAL_SETTLING_BAND_RAD) -> list[GoalReport]:
    """Return one GoalReport per goal of ``run`` (an analyze.RunData), in the order they came."""
    by_goal: dict[str, list[GoalEventRow]] = {}
    for row in run.goal_events:
        by_goal.setdefault(row.goal_id, []).append(row)
    starts = sorted((r.stamp_ns, r.goal_id) for r in run.goal_events if r.kind == 'started')
    controlled = np.isin(run.status, CONTROLLED) & np.isfinite(run.error)
    t_end = float(run.t[-1]) if run.t.size else 0.0
    reports = []
    for goal_id, rows in by_goal.items():
        kinds = {r.kind: r for r in rows}
        first = rows[0]
        accepted = kinds.get('accepted')
        report = GoalReport(
            goal_id,
            first.from_action,
            'running',
            points=accepted.points if accepted else 0,
            interpolation=accepted.interpolation if accepted else '',
        )
        reports.append(report)
        end = next((kinds[k] for k in ENDS if k in kinds), None)
        if 'refused' in kinds:
            report.result, report.error_string = 'refused', kinds['refused'].error_string
            continue
        if end is not None:
            report.result, report.error_string = end.kind, end.error_string
            report.ended_s = (end.stamp_ns - run.t0_ns) * 1e-9
        started = kinds.get('started')
        if started is None:
            continue
        report.started_s = (started.stamp_ns - run.t0_ns) * 1e-9
        report.due_s = (started.end_ns - run.t0_ns) * 1e-9
        later = [s for s, g in starts if s > started.stamp_ns and g != goal_id]
        window_end = (later[0] - run.t0_ns) * 1e-9 if later else t_end + 1e-9
        window = controlled & (run.t >= report.started_s - 1e-12) & (run.t < window_end)
        path_end = (
            min(report.due_s, report.ended_s) if report.ended_s is not None else report.due_s
        )
        path = window & (run.t <= path_end + 1e-12)
        if np.any(path):
            report.max_path_error_rad = float(np.max(np.abs(run.error[path])))
        # a goal that ended otherwise has its end (ended_s) in the bag
        settle_from = (
            report.ended_s
            if report.ended_s is not None and report.result not in ('succeeded', 'running')
            else report.due_s
        )
        after = window & (run.t >= settle_from - 1e-12)
        if np.any(after):
            errors = np.abs(run.error[after])
            report.final_error_rad = float(errors[0])
            outside = np.flatnonzero(errors > band_rad)
            if outside.size == 0:
                report.settling_time_s = 0.0
            elif outside[-1] + 1 < errors.size:
                report.settling_time_s = float(run.t[after][outside[-1] + 1] - settle_from)
        in_window = (run.t >= report.started_s - 1e-12) & (run.t < window_end)
        report.saturated_samples = int(np.count_nonzero(run.saturated[in_window]))
    return reports


def _cell(value: Optional[float], fmt: str) -> str:
    return '-' if value is None else format(value, fmt)


def format_goals(reports: list[GoalReport]) -> str:
    """Return a text table of the goals of one run (empty string when it had none)."""
    if not reports:
        return ''
    lines = [
        f'{"goal":<12} {"via":<6} {"result":<10} {"start s":>8} {"due s":>7} {"end s":>7} '
        f'{"max|e| path":>12} {"|e| end":>10} {"settle s":>9} {"at limit":>8}  reason'
    ]
    for r in reports:
        lines.append(
            f'{r.goal_id[:12]:<12} {"action" if r.from_action else "topic":<6} {r.result:<10} '
            f'{_cell(r.started_s, ".3f"):>8} {_cell(r.due_s, ".3f"):>7} '
            f'{_cell(r.ended_s, ".3f"):>7} {_cell(r.max_path_error_rad, ".3e"):>12} '
            f'{_cell(r.final_error_rad, ".3e"):>10} {_cell(r.settling_time_s, ".3f"):>9} '
            f'{r.saturated_samples:>8}  {r.error_string}'
        )
    return '\n'.join(lines)
