# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Health of one node as ROS's diagnostics show it: a level with its reason, and key-values.

ROS-free: the node hands a ``Snapshot`` (lifecycle state, monotonic counters, values, problems
it knows of) to a ``HealthMonitor`` once per report (1-2 Hz); the monitor turns it into a
``Health`` with the level of diagnostic_msgs/DiagnosticStatus (OK 0, WARN 1, ERROR 2, STALE 3):
  - STALE when an input's counter has not moved for ``stale_after_s`` while the node is active;
  - WARN or ERROR when a counter the node marked as such moved since the last report
    (refused inputs, late samples, latches), with how many;
  - WARN when the node is not active;
  - the node's own problems (a publisher conflict, a latched safe stop) at their level.
Severity, most severe first: ERROR, STALE, WARN, OK (a latched node whose input also stopped
says ERROR). Counters are read, never fed per message: the hot path pays nothing. Rates are
the counters' increase over the wall time between two reports.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum
from typing import Mapping, Optional, Sequence


class Level(IntEnum):
    """diagnostic_msgs/DiagnosticStatus levels (the message's byte constants)."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


#: Most severe last: the order in which levels combine.
SEVERITY = (Level.OK, Level.WARN, Level.STALE, Level.ERROR)
#: Default time without input before an active node is STALE [s].
STALE_AFTER_S = 1.0
#: Default period of the reports [s] (ROS diagnostics: about 1 Hz).
REPORT_PERIOD_S = 0.5


def worst(levels: Sequence[Level]) -> Level:
    """Most severe of ``levels`` (OK for none)."""
    return max(levels, key=SEVERITY.index, default=Level.OK)


@dataclass
class Snapshot:
    """What a node reports at one instant."""

    state: str  #: lifecycle state: unconfigured, inactive, active, finalized
    counts: Mapping[str, int] = field(default_factory=dict)  #: monotonic counters
    values: Mapping[str, object] = field(default_factory=dict)  #: shown as they are
    problems: Sequence[tuple[Level, str]] = ()  #: conditions the node knows of, with a level


@dataclass(frozen=True)
class Health:
    """One DiagnosticStatus: component name, level, reason, key-values (all text)."""

    name: str
    hardware_id: str
    level: Level
    message: str
    values: tuple[tuple[str, str], ...]

    def value(self, key: str) -> Optional[str]:
        """Return the value of ``key``, or None."""
        return dict(self.values).get(key)


def _text(value: object) -> str:
    """Key-value text: floats with 4 significant digits, None as ''."""
    if value is None:
        return ''
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f'{value:.4g}'
    return str(value)


def _matching(rule: str, what: str, delta: Mapping[str, int]) -> list[tuple[str, str]]:
    """(counter, text) of the counters a rule names that moved.

    ``'refused *'`` names every counter starting with ``'refused '``, its text says which.
    """
    if not rule.endswith('*'):
        return [(rule, what)] if delta.get(rule, 0) > 0 else []
    prefix = rule[:-1]
    return [
        (c, f'{what} ({c[len(prefix) :]})') for c in delta if c.startswith(prefix) and delta[c] > 0
    ]


class HealthMonitor:
    """Turns successive snapshots of one node into Health reports."""

    def __init__(
        self,
        name: str,
        *,
        inputs: Optional[Mapping[str, str]] = None,
        warn_on: Optional[Mapping[str, str]] = None,
        error_on: Optional[Mapping[str, str]] = None,
        stale_after_s: float = STALE_AFTER_S,
        hardware_id: str = '',
    ) -> None:
        """Name the counters: ``inputs`` counter -> topic; ``warn_on``/``error_on`` -> what.

        A counter of ``inputs`` that does not move for ``stale_after_s`` makes an active node
        STALE. A rule ending in ``*`` (``'refused *'``) covers every counter with that prefix.
        """
        if not stale_after_s > 0:
            raise ValueError(f'stale_after_s must be > 0, not {stale_after_s}')
        self.name, self.hardware_id = name, hardware_id
        self.inputs = dict(inputs or {})
        self.warn_on, self.error_on = dict(warn_on or {}), dict(error_on or {})
        self.stale_after_ns = int(stale_after_s * 1e9)
        self._last_ns: Optional[int] = None
        self._last_counts: dict[str, int] = {}
        self._moved_ns: dict[str, int] = {}  # per input: when its counter last moved
        self.reports = 0

    def update(self, now_ns: int, snap: Snapshot) -> Health:
        """Judge the node's snapshot at ``now_ns`` (a monotonic wall clock)."""
        active = snap.state == 'active'
        dt_s = None if self._last_ns is None else (now_ns - self._last_ns) * 1e-9
        # A counter not reported before counts from 0 (a first refusal of a new reason).
        delta = {k: int(v) - self._last_counts.get(k, 0) for k, v in snap.counts.items()}
        problems: list[tuple[Level, str]] = list(snap.problems)
        if not active:
            problems.append((Level.WARN, f'not active ({snap.state})'))
        for counter, topic in self.inputs.items():
            if not active or delta.get(counter, 0) > 0 or counter not in self._moved_ns:
                self._moved_ns[counter] = now_ns  # the clock restarts on (re)activation
            silent_ns = now_ns - self._moved_ns[counter]
            if active and silent_ns >= self.stale_after_ns:
                problems.append((Level.STALE, f'no {topic} for {silent_ns * 1e-9:.1f} s'))
        for rules, level in ((self.warn_on, Level.WARN), (self.error_on, Level.ERROR)):
            for rule, what in rules.items():
                for counter, why in _matching(rule, what, delta):
                    problems.append((level, f'{delta[counter]} {why} since the last report'))
        level = worst([lv for lv, _ in problems])
        reasons = [why for lv, why in sorted(problems, key=lambda p: -SEVERITY.index(p[0]))]
        values: list[tuple[str, str]] = [('lifecycle_state', snap.state)]
        values += [(k, _text(v)) for k, v in snap.values.items()]
        values += [(k, str(int(v))) for k, v in snap.counts.items()]
        if dt_s and dt_s > 0:
            values += [
                (f'{topic} rate [Hz]', f'{delta.get(counter, 0) / dt_s:.1f}')
                for counter, topic in self.inputs.items()
            ]
        self._last_ns, self._last_counts = now_ns, {k: int(v) for k, v in snap.counts.items()}
        self.reports += 1
        return Health(
            self.name, self.hardware_id, level, '; '.join(reasons) or 'ok', tuple(values)
        )
