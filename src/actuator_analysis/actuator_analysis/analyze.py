# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``bag_analyze``: compare recorded runs offline and draw the paper's figures.

No ROS graph is needed. Each bag is read with rosbags; message types come from the installed
.msg files (or, for types not installed, the definitions embedded in the bag). Per bag it
reports the run metrics of ``actuator_core.metrics.compute_run_metrics`` computed from the
``controller/state`` samples (reference, error, prescribed-performance bounds, current),
the estimation error of ``eso/estimate`` against ``plant/truth`` paired by header.stamp,
and loop timing from stamps: the joint_states sample period and the command latency
(the recorder's receive time of ``current_command`` minus its header.stamp).

Time zero of a run is the header.stamp of its first controller/state sample that is not
Status.WAITING (actuator_core.status); samples before it (controller waiting for inputs) are
left out.

The clock of a bag is told from its content, whoever recorded it (this project's recorder or
``ros2 bag record``): header stamps before 2000-01-01 are sim time (the plant's /clock starts at
0), later ones wall time, and likewise the log times. The recorder delay (log time minus stamp)
is read only when both are wall time: a sim-time log says when /clock had advanced, and a
wall-clock log of sim-time stamps differs from them by the epoch. ``/diagnostics``
(diagnostic_msgs/DiagnosticArray), where recorded, is summarised per component: reports per
level and the reasons of the worst.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Sequence

import numpy as np

from actuator_bag.errors import AnalysisError
from actuator_bag.msgdefs import DefinitionSource
from actuator_bag.progress import Progress
from actuator_bag.reading import bag_typestore, find_topic, open_bag, topic_names
from actuator_core.metrics import STEADY_STATE_START_S, RunMetrics, compute_run_metrics
from actuator_core.stats import missed_samples
from actuator_core.status import CONTROLLED, Status
from actuator_core.timing import stamp_to_ns

from .goals import goal_event_row
from .mismatch import B0Mismatch, b0_mismatch

CONTROLLER_STATE = 'actuator_msgs/msg/ControllerState'
STATE_ESTIMATE = 'actuator_msgs/msg/StateEstimate'
PLANT_TRUTH = 'actuator_msgs/msg/PlantTruth'
CURRENT_COMMAND = 'actuator_msgs/msg/CurrentCommand'
JOINT_STATE = 'sensor_msgs/msg/JointState'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
GOAL_EVENT = 'actuator_msgs/msg/GoalEvent'
#: Stamps and log times before this are on a sim clock (2000-01-01T00:00:00Z) [ns].
WALL_CLOCK_START_NS = 946_684_800 * 1_000_000_000
#: The observer's input current and the one the joint held are the same float when the command
#: reached both in time; a difference beyond this is a sample the observer integrated wrong [A].
OBSERVER_INPUT_TOLERANCE_A = 1e-9
#: diagnostic_msgs/DiagnosticStatus level names, by value.
DIAGNOSTIC_LEVELS = ('OK', 'WARN', 'ERROR', 'STALE')


@dataclass
class RunData:
    """The arrays of one bag that the metrics and figures need; times in s from the run start."""

    name: str
    path: Path
    controller: str
    t0_ns: int
    t: np.ndarray
    reference: np.ndarray
    measured: np.ndarray
    error: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    current: np.ndarray
    saturated: np.ndarray
    status: np.ndarray
    est_t: np.ndarray = field(default_factory=lambda: np.empty(0))
    est_velocity: np.ndarray = field(default_factory=lambda: np.empty(0))
    est_disturbance: np.ndarray = field(default_factory=lambda: np.empty(0))
    truth_t: np.ndarray = field(default_factory=lambda: np.empty(0))
    truth_velocity: np.ndarray = field(default_factory=lambda: np.empty(0))
    truth_disturbance: np.ndarray = field(default_factory=lambda: np.empty(0))
    velocity_error: Optional[np.ndarray] = None
    #: Per sample both topics cover: the current the observer integrated over the interval before
    #: it (eso/estimate input_current_a) minus the current the joint held there (plant/truth
    #: current_a) [A]; nonzero where a command reached the observer but not the joint in time.
    observer_input_error_a: Optional[np.ndarray] = None
    #: eso/estimate input_current_gain per estimate: dt theta1n, the observer's b0 times dt.
    est_current_gain: np.ndarray = field(default_factory=lambda: np.empty(0))
    disturbance_error: Optional[np.ndarray] = None
    sample_period_s: np.ndarray = field(default_factory=lambda: np.empty(0))
    command_latency_s: np.ndarray = field(default_factory=lambda: np.empty(0))
    #: 'sim' or 'wall', told from the stamps; the log times' clock likewise.
    stamp_clock: str = 'wall'
    log_clock: str = ''
    #: Per /diagnostics component, over the run (the joint's first to last sample): {'levels':
    #: {level: reports}, 'worst': level, 'reasons': [..], 'before_run': {..}, 'after_run': {..}}.
    diagnostics: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: controller/goal_events in stamp order: actuator_analysis.goals.GoalEventRow each.
    goal_events: list = field(default_factory=list)

    @property
    def has_envelope(self) -> bool:
        """True when the prescribed-performance bounds are finite at every controlled sample.

        Controlled samples are those of status OK or RECOVERING (the law ran).
        """
        ok = np.isin(self.status, CONTROLLED)
        return bool(
            ok.any()
            and np.all(np.isfinite(self.lower[ok]))
            and np.all(np.isfinite(self.upper[ok]))
        )


@dataclass
class RunReport:
    """Metrics and timing figures of one bag."""

    run: RunData
    metrics: RunMetrics
    timing: dict[str, Optional[dict[str, float]]]
    missed_samples: int
    b0: Optional[B0Mismatch] = None  # the joint's theta1 as the run shows it (mismatch)

    def as_dict(self) -> dict[str, Any]:
        """Plain-dict form for JSON output."""
        return {
            'bag': str(self.run.path),
            'controller': self.run.controller,
            'has_envelope': self.run.has_envelope,
            'status_not_ok_fraction': float(np.mean(self.run.status != Status.OK)),
            'metrics': self.metrics.as_dict(),
            'timing': self.timing,
            'missed_samples': self.missed_samples,
            'clock': {'stamps': self.run.stamp_clock, 'log_times': self.run.log_clock},
            'steady_window_empty': steady_empty(self.metrics),
            'diagnostics': self.run.diagnostics,
            'observer_input': observer_input(self.run),
            'b0_mismatch': None if self.b0 is None else self.b0.as_dict(),
        }


def observer_input(run: RunData) -> Optional[dict[str, float]]:
    """How often and how far the observer's input current left the one the joint held.

    None without both eso/estimate and plant/truth (a hardware bag).
    """
    diff = run.observer_input_error_a
    if diff is None or not diff.size:
        return None
    off = np.abs(diff) > OBSERVER_INPUT_TOLERANCE_A
    return {
        'samples': int(diff.size),
        'differing': int(np.count_nonzero(off)),
        'max_abs_a': float(np.max(np.abs(diff))),
    }


def load_run(
    path: os.PathLike | str, source: Optional[DefinitionSource] = None, quiet: bool = False
) -> RunData:
    """Read the topics of one bag into a RunData.

    AnalysisError when controller/state is missing or empty.
    """
    path = Path(path)
    with open_bag(path) as reader:
        conns = reader.connections
        state = find_topic(conns, CONTROLLER_STATE, 'controller/state')
        if state is None:
            raise AnalysisError(
                f'{path}: no {CONTROLLER_STATE} topic (controller/state) to analyse; '
                f'the bag has: {topic_names(conns)}'
            )
        wanted = {
            'state': state,
            'estimate': find_topic(conns, STATE_ESTIMATE, 'eso/estimate'),
            'truth': find_topic(conns, PLANT_TRUTH, 'plant/truth'),
            'joint': find_topic(conns, JOINT_STATE, 'joint_states'),
            'command': find_topic(conns, CURRENT_COMMAND, 'current_command'),
            'diagnostics': find_topic(conns, DIAGNOSTIC_ARRAY, '/diagnostics'),
            'goals': find_topic(conns, GOAL_EVENT, 'controller/goal_events'),
        }
        present = {k: c for k, c in wanted.items() if c is not None}
        by_id = {c.id: k for k, c in present.items()}
        # Only the analysed topics need a definition: an `ros2 bag record -a` bag may hold types
        # that are neither installed nor described in the bag.
        store = bag_typestore(reader, source, list(present.values()))
        rows: dict[str, list[tuple]] = {k: [] for k in present}
        total = sum(c.msgcount for c in present.values())
        progress = Progress(f'bag_analyze {path.name}', total, unit='messages', enabled=not quiet)
        done = 0
        for conn, log_ns, raw in reader.messages(connections=list(present.values())):
            kind = by_id[conn.id]
            try:
                msg = store.deserialize_cdr(raw, conn.msgtype)
            except Exception as err:  # noqa: BLE001 - any decode failure is a bad bag
                raise AnalysisError(
                    f'{path}: a {conn.topic} message does not decode ({err})'
                ) from None
            rows[kind].append(_extract(kind, msg, log_ns))
            done += 1
            if done % 1000 == 0:
                progress.update(done)
        progress.update(done)
    return _assemble(path, rows)


def _level(value: Any) -> int:
    """Return a DiagnosticStatus level as an int (rosbags: the byte field as int or bytes)."""
    return value[0] if isinstance(value, (bytes, bytearray)) else int(value)


def clock_of(ns: np.ndarray) -> str:
    """'sim' when the median time is before 2000 (a /clock from 0), else 'wall'; '' for none."""
    if ns.size == 0:
        return ''
    return 'sim' if float(np.median(ns)) < WALL_CLOCK_START_NS else 'wall'


def summarize_diagnostics(
    reports: Sequence[tuple], window_ns: Optional[tuple[int, int]] = None
) -> dict[str, dict[str, Any]]:
    """Per component: reports per level, the worst level, its distinct reasons (first 5).

    ``reports``: (stamp ns, name, level, message). With ``window_ns`` (the run: the joint's first
    and last sample) only the reports stamped inside it are judged; those after it (the nodes
    report their inputs' end as stale while the run shuts down) are counted per level under
    'after_run', those before it (start-up) under 'before_run'. 'worst' is None for a component
    with no report judged (none stamped inside the run).
    """
    out: dict[str, dict[str, Any]] = {}
    severity = ('OK', 'WARN', 'STALE', 'ERROR')
    for stamp, name, level, message in reports:
        entry = out.setdefault(
            name, {'levels': {}, 'worst': None, 'reasons': [], 'before_run': {}, 'after_run': {}}
        )
        label = DIAGNOSTIC_LEVELS[level] if 0 <= level < len(DIAGNOSTIC_LEVELS) else str(level)
        if window_ns is not None and not window_ns[0] <= stamp < window_ns[1]:
            side = entry['before_run' if stamp < window_ns[0] else 'after_run']
            side[label] = side.get(label, 0) + 1
            continue
        entry['levels'][label] = entry['levels'].get(label, 0) + 1
        rank = severity.index(label) if label in severity else len(severity)
        worst = severity.index(entry['worst']) if entry['worst'] in severity else len(severity)
        if entry['worst'] is None or rank > worst:
            entry['worst'], entry['reasons'] = label, []
        if label == entry['worst'] and label != 'OK' and message not in entry['reasons']:
            if len(entry['reasons']) < 5:
                entry['reasons'].append(message)
    return out


def _extract(kind: str, msg: Any, log_ns: int) -> tuple:
    """Return the fields of one message that the analysis uses."""
    if kind == 'state':
        return (
            stamp_to_ns(msg.header.stamp),
            msg.controller_name,
            int(msg.status),
            msg.reference_position_rad,
            msg.measured_position_rad,
            msg.error_rad,
            msg.lower_bound_rad,
            msg.upper_bound_rad,
            msg.current_a,
            bool(msg.saturated),
        )
    if kind == 'estimate':
        return (
            stamp_to_ns(msg.header.stamp),
            msg.velocity_rad_s,
            msg.disturbance_rad_s2,
            msg.input_current_a,
            msg.input_current_gain,
        )
    if kind == 'truth':
        return (
            stamp_to_ns(msg.header.stamp),
            msg.velocity_rad_s,
            msg.disturbance_rad_s2,
            msg.current_a,
        )
    if kind == 'diagnostics':
        stamp = stamp_to_ns(msg.header.stamp)
        return tuple((stamp, s.name, _level(s.level), s.message) for s in msg.status)
    if kind == 'goals':
        return goal_event_row(msg)
    return (stamp_to_ns(msg.header.stamp), int(log_ns))


def _assemble(path: Path, rows: dict[str, list[tuple]]) -> RunData:
    """Turn message rows into time-aligned arrays."""
    states = sorted((r for r in rows['state'] if r[2] != Status.WAITING), key=lambda r: r[0])
    if not states:
        raise AnalysisError(
            f'{path}: controller/state has no samples past start-up (all Status.WAITING or none)'
        )
    t0 = states[0][0]
    names = sorted({r[1] for r in states if r[1]})
    cols = list(zip(*states))
    run = RunData(
        name=path.name if path.is_dir() else path.stem,
        path=path,
        controller='+'.join(names) or 'unknown',
        t0_ns=t0,
        t=(np.asarray(cols[0], dtype=np.int64) - t0) * 1e-9,
        reference=np.asarray(cols[3], dtype=float),
        measured=np.asarray(cols[4], dtype=float),
        error=np.asarray(cols[5], dtype=float),
        lower=np.asarray(cols[6], dtype=float),
        upper=np.asarray(cols[7], dtype=float),
        current=np.asarray(cols[8], dtype=float),
        saturated=np.asarray(cols[9], dtype=bool),
        status=np.asarray(cols[2], dtype=np.int64),
    )
    estimates = {r[0]: r for r in rows.get('estimate', [])}
    truths = {r[0]: r for r in rows.get('truth', [])}
    if estimates:
        ordered = sorted(estimates.values())
        run.est_t = (np.array([r[0] for r in ordered], dtype=np.int64) - t0) * 1e-9
        run.est_velocity = np.array([r[1] for r in ordered], dtype=float)
        run.est_disturbance = np.array([r[2] for r in ordered], dtype=float)
        run.est_current_gain = np.array([r[4] for r in ordered], dtype=float)
    if truths:
        ordered = sorted(truths.values())
        run.truth_t = (np.array([r[0] for r in ordered], dtype=np.int64) - t0) * 1e-9
        run.truth_velocity = np.array([r[1] for r in ordered], dtype=float)
        run.truth_disturbance = np.array([r[2] for r in ordered], dtype=float)
    common = sorted(set(estimates) & set(truths))
    if common:
        run.velocity_error = np.array(
            [estimates[s][1] - truths[s][1] for s in common], dtype=float
        )
        run.disturbance_error = np.array(
            [estimates[s][2] - truths[s][2] for s in common], dtype=float
        )
        run.observer_input_error_a = np.array(
            [estimates[s][3] - truths[s][3] for s in common], dtype=float
        )
    joint = sorted({r[0] for r in rows.get('joint', [])})
    if len(joint) > 1:
        run.sample_period_s = np.diff(np.asarray(joint, dtype=np.int64)) * 1e-9
    run.stamp_clock = clock_of(np.asarray(cols[0], dtype=np.int64))
    if rows.get('command'):
        stamps, logs = (np.asarray(c, dtype=np.int64) for c in zip(*rows['command']))
        run.log_clock = clock_of(logs)
        if run.log_clock == 'wall' and clock_of(stamps) == 'wall':
            run.command_latency_s = (logs - stamps) * 1e-9
    window = (joint[0], joint[-1]) if len(joint) > 1 else None
    run.diagnostics = summarize_diagnostics(
        [status for statuses in rows.get('diagnostics', []) for status in statuses], window
    )
    run.goal_events = sorted(rows.get('goals', []), key=lambda r: r.stamp_ns)
    return run


def _stats(values: np.ndarray) -> Optional[dict[str, float]]:
    """p50/p99/max of an array [s], or None when empty."""
    if values.size == 0:
        return None
    return {
        'p50_s': float(np.percentile(values, 50)),
        'p99_s': float(np.percentile(values, 99)),
        'max_s': float(np.max(values)),
    }


def analyze_run(run: RunData, steady_state_start_s: float = STEADY_STATE_START_S) -> RunReport:
    """Metrics (shared compute_run_metrics) over the controlled samples, and timing of one run.

    A safe-stop sample carries no error (NaN: the law did not run), so the error figures are
    taken over the samples the law controlled (OK, RECOVERING); a run that latched its safe
    stop is reported as diverged, whatever its error was before.
    """
    ok = np.isin(run.status, CONTROLLED)
    if not ok.any():
        raise AnalysisError(
            f'{run.path}: no sample of controller/state was controlled (status OK or RECOVERING)'
        )
    metrics = compute_run_metrics(
        run.t[ok],
        run.error[ok],
        run.current[ok],
        lower_bound=run.lower[ok] if run.has_envelope else None,
        upper_bound=run.upper[ok] if run.has_envelope else None,
        saturated=run.saturated[ok],
        velocity_estimate_error=run.velocity_error,
        disturbance_estimate_error=run.disturbance_error,
        steady_state_start_s=steady_state_start_s,
    )
    if np.any(run.status == Status.LATCHED):
        metrics = dataclasses.replace(metrics, diverged=True, bounds_kept=False)
    period = run.sample_period_s
    missed = 0
    if period.size:
        nominal_ns = int(round(float(np.median(period)) * 1e9))
        if nominal_ns > 0:
            missed = missed_samples(
                np.concatenate(([0], np.cumsum(np.rint(period * 1e9).astype(np.int64)))),
                nominal_ns,
            )
    timing = {'sample_period': _stats(period), 'command_latency': _stats(run.command_latency_s)}
    return RunReport(run, metrics, timing, missed, run_b0_mismatch(run))


def run_b0_mismatch(run: RunData) -> Optional[B0Mismatch]:
    """Return the observer's b0 against the joint's theta1 as the run shows it (``mismatch``).

    The current held before sample k is the command of sample k - 1; theta1n is read from
    eso/estimate (None without it).
    """
    if run.t.size < 3:
        return None
    dt = float(np.median(np.diff(run.t)))
    theta1n = None
    if run.est_current_gain.size > 1 and dt > 0:
        theta1n = float(np.median(run.est_current_gain)) / float(np.median(np.diff(run.est_t)))
    held = np.concatenate(([0.0], run.current[:-1]))
    usable = np.isin(run.status, CONTROLLED) & np.isfinite(run.measured)
    if usable.sum() < 2:
        return None
    index = np.arange(run.t.size)  # the angle through the unusable samples: their windows are
    angle = np.interp(index, index[usable], run.measured[usable])  # skipped, not the filter's
    return b0_mismatch(angle, held, dt, usable, theta1n or None)


def steady_empty(metrics: RunMetrics) -> bool:
    """Tell whether the run ends before its steady window starts."""
    start, end = metrics.steady_window_s
    return end < start
