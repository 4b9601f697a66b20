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
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Sequence

import numpy as np
import yaml
from tabulate import tabulate
from actuator_core.metrics import STEADY_STATE_START_S, RunMetrics, compute_run_metrics
from actuator_core.stats import missed_samples
from actuator_core.status import Status
from actuator_core.timing import stamp_to_ns

from .errors import AnalysisError, BagError, run_cli
from .msgdefs import DefinitionSource, definition_roots
from .outputs import check_output_file, check_output_folder
from .progress import Progress
from .reading import bag_typestore, find_topic, open_bag, topic_names

CONTROLLER_STATE = 'actuator_msgs/msg/ControllerState'
STATE_ESTIMATE = 'actuator_msgs/msg/StateEstimate'
PLANT_TRUTH = 'actuator_msgs/msg/PlantTruth'
CURRENT_COMMAND = 'actuator_msgs/msg/CurrentCommand'
JOINT_STATE = 'sensor_msgs/msg/JointState'
#: The files draw_figures writes (the velocity and disturbance figures only when a bag has
#: estimates).
FIGURE_FILES = (
    'position.png',
    'tracking_error.png',
    'velocity_estimate.png',
    'disturbance_estimate.png',
    'control_input.png',
)


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
    disturbance_error: Optional[np.ndarray] = None
    sample_period_s: np.ndarray = field(default_factory=lambda: np.empty(0))
    command_latency_s: np.ndarray = field(default_factory=lambda: np.empty(0))

    @property
    def has_envelope(self) -> bool:
        """True when the prescribed-performance bounds are finite at every controlled sample.

        Controlled samples are those of status OK.
        """
        ok = self.status == Status.OK
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
        }
        present = {k: c for k, c in wanted.items() if c is not None}
        by_id = {c.id: k for k, c in present.items()}
        store = bag_typestore(reader, source)
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
    run = _assemble(path, rows)
    if _logged_in_sim_time(path):
        # Log times on a sim clock say when /clock had advanced, not when a message arrived:
        # no latency can be read from them.
        run.command_latency_s = np.empty(0)
    return run


def _logged_in_sim_time(path: Path) -> bool:
    """Tell whether the recorder wrote log times on sim time (metadata.yaml custom_data)."""
    meta = path / 'metadata.yaml' if path.is_dir() else path.parent / 'metadata.yaml'
    try:
        info = yaml.safe_load(meta.read_text())['rosbag2_bagfile_information']
        return 'sim time' in str((info.get('custom_data') or {}).get('log_time', ''))
    except (OSError, KeyError, TypeError, yaml.YAMLError):
        return False


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
        return (stamp_to_ns(msg.header.stamp), msg.velocity_rad_s, msg.disturbance_rad_s2)
    if kind == 'truth':
        return (stamp_to_ns(msg.header.stamp), msg.velocity_rad_s, msg.disturbance_rad_s2)
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
    joint = sorted({r[0] for r in rows.get('joint', [])})
    if len(joint) > 1:
        run.sample_period_s = np.diff(np.asarray(joint, dtype=np.int64)) * 1e-9
    if rows.get('command'):
        run.command_latency_s = np.array(
            [(log - stamp) * 1e-9 for stamp, log in rows['command']], dtype=float
        )
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
    taken over the samples with status OK; a run that latched its safe stop is reported as
    diverged, whatever its error was before.
    """
    ok = run.status == Status.OK
    if not ok.any():
        raise AnalysisError(f'{run.path}: no sample of controller/state has status OK')
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
    return RunReport(run=run, metrics=metrics, timing=timing, missed_samples=missed)


def _num(value: Optional[float], unit: str, fmt: str = '.3e') -> str:
    """Format a number with its unit, or n/a."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return 'n/a'
    return f'{value:{fmt}} {unit}'


def _timing(stats: Optional[dict[str, float]]) -> str:
    """p50/p99/max in ms, or n/a."""
    if not stats:
        return 'n/a'
    return '{:.3f}/{:.3f}/{:.3f} ms'.format(
        stats['p50_s'] * 1e3, stats['p99_s'] * 1e3, stats['max_s'] * 1e3
    )


def format_table(reports: Sequence[RunReport]) -> str:
    """Format a text table: one row per figure, one column per bag."""
    rows: list[tuple[str, list[str]]] = []

    def add(label: str, cells: list[str]) -> None:
        rows.append((label, cells))

    add('bag', [r.run.name for r in reports])
    add('controller', [r.run.controller for r in reports])
    add(
        'samples / duration',
        [f'{r.metrics.samples} / {r.metrics.duration_s:.3f} s' for r in reports],
    )
    add('diverged', ['YES' if r.metrics.diverged else 'no' for r in reports])
    add(
        'status not OK',
        [f'{100 * np.mean(r.run.status != Status.OK):.2f} % of samples' for r in reports],
    )
    add('steady window', ['{:.1f}-{:.3f} s'.format(*r.metrics.steady_window_s) for r in reports])
    add('max |e| in steady window', [_num(r.metrics.max_steady_error_rad, 'rad') for r in reports])
    add('RMS e in steady window', [_num(r.metrics.rms_steady_error_rad, 'rad') for r in reports])
    add('RMS e whole run', [_num(r.metrics.rms_error_rad, 'rad') for r in reports])
    add('max |u|', [_num(r.metrics.max_abs_current_a, 'A', '.4f') for r in reports])
    add('RMS u', [_num(r.metrics.rms_current_a, 'A', '.4f') for r in reports])
    add('saturated', [f'{100 * r.metrics.saturated_fraction:.2f} %' for r in reports])
    add(
        'PPF bounds',
        [
            (
                'kept'
                if r.metrics.bounds_kept
                else f'VIOLATED at {r.metrics.bounds_violations} samples'
            )
            if r.run.has_envelope
            else 'n/a (no envelope)'
            for r in reports
        ],
    )
    add(
        'RMS velocity est. error',
        [
            _num(r.metrics.rms_velocity_estimate_error_rad_s, 'rad/s')
            if r.run.velocity_error is not None
            else 'n/a (no truth)'
            for r in reports
        ],
    )
    add(
        'RMS disturbance est. error',
        [
            _num(r.metrics.rms_disturbance_estimate_error_rad_s2, 'rad/s^2')
            if r.run.disturbance_error is not None
            else 'n/a (no truth)'
            for r in reports
        ],
    )
    add('sample period p50/p99/max', [_timing(r.timing['sample_period']) for r in reports])
    add(
        'missed samples',
        [str(r.missed_samples) if r.timing['sample_period'] else 'n/a' for r in reports],
    )
    # The recorder's receive time minus the stamp: the recorder's own delay (it runs at normal
    # scheduling), not the loop's latency, which the controller measures (timing log).
    add(
        'recorder delay (log - stamp) p50/p99/max',
        [_timing(r.timing['command_latency']) for r in reports],
    )
    (_, names), body = rows[0], rows[1:]
    return tabulate(
        [(label, *cells) for label, cells in body],
        headers=('bag', *names),
        tablefmt='simple',
        disable_numparse=True,
    )


def _labels(runs: Sequence[RunData]) -> list[str]:
    """Legend labels: controller names, made unique with the bag name when they repeat."""
    names = [r.controller for r in runs]
    return [n if names.count(n) == 1 else f'{n} ({r.name})' for n, r in zip(names, runs)]


def draw_figures(runs: Sequence[RunData], out: Path) -> list[Path]:
    """Write the paper's figures as PNG files into ``out``; return their paths."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    labels = _labels(runs)
    written: list[Path] = []

    def save(fig: Any, name: str) -> None:
        path = out / name
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)

    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.plot(runs[0].t, runs[0].reference, 'k--', linewidth=1.2, label='reference')
    for run, label in zip(runs, labels):
        ax.plot(run.t, run.measured, linewidth=0.9, label=label)
    ax.set(xlabel='time [s]', ylabel='joint angle [rad]', title='Position response')
    ax.legend(loc='best', fontsize='small')
    ax.grid(True, alpha=0.3)
    save(fig, 'position.png')

    # Two panels, as the paper's Figures 5b and 6b zoom: the whole run with the envelope, and the
    # steady window at the error's own scale (the +-0.25 rad bounds flatten a 1e-3 rad error).
    fig, (ax, zoom) = plt.subplots(2, 1, figsize=(8, 7))
    steady_peak = 0.0
    for run, label in zip(runs, labels):
        (line,) = ax.plot(run.t, run.error, linewidth=0.9, label=label)
        if run.has_envelope:
            ax.plot(run.t, run.upper, ':', color=line.get_color(), linewidth=1.0)
            ax.plot(
                run.t,
                run.lower,
                ':',
                color=line.get_color(),
                linewidth=1.0,
                label=f'{label} bounds',
            )
        steady = (run.t >= STEADY_STATE_START_S) & np.isfinite(run.error)
        zoom.plot(
            run.t[steady], run.error[steady], linewidth=0.9, color=line.get_color(), label=label
        )
        if steady.any():
            steady_peak = max(steady_peak, float(np.max(np.abs(run.error[steady]))))
    ax.set(
        xlabel='time [s]',
        ylabel='tracking error e [rad]',
        title='Tracking error and prescribed performance bounds',
    )
    ax.legend(loc='best', fontsize='small')
    ax.grid(True, alpha=0.3)
    if steady_peak > 0.0:
        zoom.set_ylim(-1.2 * steady_peak, 1.2 * steady_peak)
    zoom.set(
        xlabel='time [s]',
        ylabel='tracking error e [rad]',
        title=f'Steady window (t >= {STEADY_STATE_START_S:g} s) at its own scale',
    )
    zoom.ticklabel_format(axis='y', style='sci', scilimits=(-2, 2))
    zoom.grid(True, alpha=0.3)
    save(fig, 'tracking_error.png')

    for name, title, unit, est_attr, truth_attr in (
        (
            'velocity_estimate.png',
            'Velocity estimate vs truth',
            'velocity [rad/s]',
            'est_velocity',
            'truth_velocity',
        ),
        (
            'disturbance_estimate.png',
            'Disturbance estimate vs truth',
            'disturbance [rad/s^2]',
            'est_disturbance',
            'truth_disturbance',
        ),
    ):
        with_data = [(r, lab) for r, lab in zip(runs, labels) if getattr(r, est_attr).size]
        if not with_data:
            continue
        fig, ax = plt.subplots(figsize=(8, 4.5))
        for run, label in with_data:
            if getattr(run, truth_attr).size:
                ax.plot(
                    run.truth_t,
                    getattr(run, truth_attr),
                    'k-',
                    linewidth=1.0,
                    alpha=0.6,
                    label=f'truth ({label})' if len(with_data) > 1 else 'truth',
                )
            ax.plot(
                run.est_t, getattr(run, est_attr), '--', linewidth=0.9, label=f'estimate ({label})'
            )
        ax.set(xlabel='time [s]', ylabel=unit, title=title)
        ax.legend(loc='best', fontsize='small')
        ax.grid(True, alpha=0.3)
        save(fig, name)

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for run, label in zip(runs, labels):
        ax.plot(run.t, run.current, linewidth=0.8, label=label)
    ax.set(xlabel='time [s]', ylabel='motor current u [A]', title='Control input')
    ax.legend(loc='best', fontsize='small')
    ax.grid(True, alpha=0.3)
    save(fig, 'control_input.png')
    return written


def build_parser() -> argparse.ArgumentParser:
    """Command-line interface of bag_analyze."""
    parser = argparse.ArgumentParser(
        prog='bag_analyze',
        description='Compare recorded runs: tracking, control effort, PPF bound compliance, '
        'estimation error and loop timing per bag, read offline from rosbag2/MCAP bags. '
        "Draws the paper's figures with --out.",
    )
    parser.add_argument(
        'bags', nargs='+', type=Path, metavar='BAG', help='bag folders (or .mcap files)'
    )
    parser.add_argument(
        '--out',
        type=Path,
        help='write position, tracking error, estimate and input figures (PNG) here '
        '(never inside an input bag)',
    )
    parser.add_argument(
        '--json',
        type=Path,
        help='write the figures of every bag as JSON to this file (never inside an input bag)',
    )
    parser.add_argument(
        '--steady-start',
        type=float,
        default=STEADY_STATE_START_S,
        metavar='SECONDS',
        help='start of the steady-state window after the run start [s] (default: %(default)s)',
    )
    parser.add_argument(
        '--msg-path',
        type=Path,
        action='append',
        default=[],
        metavar='DIR',
        help='extra folder holding <pkg>/msg/<Type>.msg (searched first)',
    )
    parser.add_argument('-q', '--quiet', action='store_true', help='no progress lines')
    return parser


def _jsonable(value: Any) -> Any:
    """Replace non-finite floats (not valid JSON) with None, recursively."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


def _main(argv: Optional[Sequence[str]]) -> int:
    """Load, analyse, print, and write the optional JSON and figures."""
    args = build_parser().parse_args(argv)
    if not math.isfinite(args.steady_start) or args.steady_start < 0:
        raise AnalysisError(
            f'--steady-start must be a finite number >= 0, not {args.steady_start}'
        )
    # Output locations first: nothing is read or computed for a run whose results could not be
    # written.
    if args.json:
        check_output_file('--json', args.json, args.bags)
    if args.out:
        check_output_folder('--out', args.out, args.bags, FIGURE_FILES)
    source = DefinitionSource(definition_roots(args.msg_path))
    reports = []
    for bag in args.bags:
        run = load_run(bag, source, quiet=args.quiet)
        reports.append(analyze_run(run, args.steady_start))
    print(format_table(reports))
    if args.json:
        doc = _jsonable([r.as_dict() for r in reports])
        try:
            args.json.write_text(
                json.dumps(doc, indent=2, default=str, allow_nan=False) + '\n', encoding='utf-8'
            )
        except OSError as err:
            raise BagError(f'cannot write {args.json}: {err.strerror}') from None
    if args.out:
        try:
            paths = draw_figures([r.run for r in reports], args.out)
        except OSError as err:
            raise BagError(f'cannot write figures to {args.out}: {err.strerror}') from None
        print(f'figures: {", ".join(str(p) for p in paths)}')
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``bag_analyze``."""
    return run_cli('bag_analyze', _main, argv)


if __name__ == '__main__':
    raise SystemExit(main())
