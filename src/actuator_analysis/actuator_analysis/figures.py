# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The paper's figures of recorded runs (``bag_analyze --out``), as PNG files.

Position, tracking error with the PPF bounds, estimates against the truth, control input.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from actuator_core.metrics import STEADY_STATE_START_S

if TYPE_CHECKING:
    from .analyze import RunData

#: The files draw_figures writes (the velocity and disturbance figures only when a bag has
#: estimates).
FIGURE_FILES = (
    'position.png',
    'tracking_error.png',
    'velocity_estimate.png',
    'disturbance_estimate.png',
    'control_input.png',
)


def _labels(runs: Sequence[RunData]) -> list[str]:
    """Legend labels: controller names, made unique with the bag name when they repeat."""
    names = [r.controller for r in runs]
    return [n if names.count(n) == 1 else f'{n} ({r.name})' for n, r in zip(names, runs)]


def _decorate(ax: Any, ylabel: str, title: str, legend: bool = True) -> None:
    """Label a time axis and give it the small legend and light grid of every figure here."""
    ax.set(xlabel='time [s]', ylabel=ylabel, title=title)
    if legend:
        ax.legend(loc='best', fontsize='small')
    ax.grid(True, alpha=0.3)


def _tracking_error_figure(plt: Any, runs: Sequence[RunData], labels: list[str]) -> Any:
    """Draw the tracking error with the PPF bounds, and the steady window zoomed when reached."""
    # Two panels, as the paper's Figures 5b and 6b zoom: the whole run with the envelope, and the
    # steady window at the error's own scale (the +-0.25 rad bounds flatten a 1e-3 rad error);
    # the whole run alone when no run reaches the steady window.
    reaches = any(bool(np.any(run.t >= STEADY_STATE_START_S)) for run in runs)
    if reaches:
        fig, (ax, zoom) = plt.subplots(2, 1, figsize=(8, 7))
    else:
        fig, ax = plt.subplots(figsize=(8, 4.5))
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
        if reaches:
            zoom.plot(run.t[steady], run.error[steady], linewidth=0.9, color=line.get_color())
        if steady.any():
            steady_peak = max(steady_peak, float(np.max(np.abs(run.error[steady]))))
    _decorate(ax, 'tracking error e [rad]', 'Tracking error and prescribed performance bounds')
    if reaches:
        if steady_peak > 0.0:
            zoom.set_ylim(-1.2 * steady_peak, 1.2 * steady_peak)
        steady_title = f'Steady window (t >= {STEADY_STATE_START_S:g} s) at its own scale'
        _decorate(zoom, 'tracking error e [rad]', steady_title, legend=False)
        zoom.ticklabel_format(axis='y', style='sci', scilimits=(-2, 2))
    return fig


#: The estimate figures: file, title, y label, estimate attribute, truth attribute of RunData.
_ESTIMATE_FIGURES = (
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
)


def _estimate_figure(
    plt: Any,
    runs: Sequence[RunData],
    labels: list[str],
    title: str,
    unit: str,
    est_attr: str,
    truth_attr: str,
) -> Any:
    """Draw one estimate against its truth for the runs that have it (None: no run has it)."""
    with_data = [(r, lab) for r, lab in zip(runs, labels) if getattr(r, est_attr).size]
    if not with_data:
        return None
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
    _decorate(ax, unit, title)
    return fig


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
    _decorate(ax, 'joint angle [rad]', 'Position response')
    save(fig, 'position.png')

    save(_tracking_error_figure(plt, runs, labels), 'tracking_error.png')

    for name, title, unit, est_attr, truth_attr in _ESTIMATE_FIGURES:
        fig = _estimate_figure(plt, runs, labels, title, unit, est_attr, truth_attr)
        if fig is not None:
            save(fig, name)

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for run, label in zip(runs, labels):
        ax.plot(run.t, run.current, linewidth=0.8, label=label)
    _decorate(ax, 'motor current u [A]', 'Control input')
    save(fig, 'control_input.png')
    return written
