# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Figures of a study (matplotlib, Agg): maps over two chosen quantities, CDFs over random draws.

Map: three panels over (x, y): max steady-state error (log10, rad), fraction of samples at the
current limit, fraction of samples outside the PPF envelope (8) as prescribed from t = 0 (the
controller's restarts of resolution 22 are not counted as a new envelope). A grid study is drawn
cell by cell (one cell per grid point, labelled with its values, whatever their spacing), each cell
the worst over every other varied quantity; a random study as a scatter. Diverged runs are drawn in
black and counted in the panel title. CDF: empirical distribution of the same three figures over
all runs; a diverged run counts as an infinite error, so the error CDF ends below 1 by the diverged
fraction.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

PANELS = (
    ('max_steady_error_rad', 'max steady-state error [rad] (log10)', True),
    ('saturated_fraction', 'fraction of samples at the current limit', False),
    ('paper_envelope_violation_fraction', 'fraction of samples outside the envelope (8)', False),
)


def _columns(table) -> dict[str, np.ndarray]:
    """Return a pyarrow table as float arrays (booleans as 0/1)."""
    return {n: np.asarray(table.column(n).to_pylist(), dtype=float) for n in table.column_names}


def _worst_grid(x, y, z, diverged):
    """Return the unique x, y and the worst z per cell (NaN cell where any run diverged).

    And the diverged mask.
    """
    xs, ys = np.unique(x), np.unique(y)
    grid = np.full((ys.size, xs.size), -np.inf)
    bad = np.zeros_like(grid, dtype=bool)
    ix, iy = np.searchsorted(xs, x), np.searchsorted(ys, y)
    for i, j, v, d in zip(iy, ix, z, diverged):
        if d:
            bad[i, j] = True
        elif np.isfinite(v):
            grid[i, j] = max(grid[i, j], v)
    grid[bad | ~np.isfinite(grid)] = np.nan
    return xs, ys, grid, bad


def _label_cells(ax, xs: np.ndarray, ys: np.ndarray, most: int = 8) -> None:
    """Tick labels with the grid values at the cell centres (at most ``most`` per axis)."""
    for values, set_ticks, set_labels in (
        (xs, ax.set_xticks, ax.set_xticklabels),
        (ys, ax.set_yticks, ax.set_yticklabels),
    ):
        keep = np.arange(0, values.size, max(1, -(-values.size // most)))
        set_ticks(keep + 0.5)
        set_labels([f'{v:g}' for v in values[keep]], fontsize=7)


def draw_maps(table, x_name: str, y_name: str, path: Path, grid: bool, title: str = '') -> Path:
    """Three maps over (x_name, y_name) into ``path`` (PNG)."""
    c = _columns(table)
    x, y, diverged = c[x_name], c[y_name], c['diverged'] > 0
    fig, axes = plt.subplots(1, 3, figsize=(13.5, 3.9), constrained_layout=True)
    for ax, (metric, label, log) in zip(axes, PANELS):
        z = c[metric]
        z = np.log10(np.where(z > 0, z, np.nan)) if log else z
        if grid:
            xs, ys, cells, bad = _worst_grid(x, y, z, diverged)
            mesh = ax.pcolormesh(cells, cmap='viridis')  # one cell per grid point, any spacing
            if bad.any():
                ax.pcolormesh(np.where(bad, 1.0, np.nan), cmap='gray', vmin=2, vmax=3)
            _label_cells(ax, xs, ys)
        else:
            mesh = ax.scatter(x[~diverged], y[~diverged], c=z[~diverged], s=14, cmap='viridis')
            ax.scatter(x[diverged], y[diverged], c='k', s=14, marker='x')
        fig.colorbar(mesh, ax=ax)
        ax.set_title(
            f'{label}\n{int(diverged.sum())} of {diverged.size} runs diverged (black)', fontsize=9
        )
        ax.set_xlabel(x_name)
        ax.set_ylabel(y_name)
    return _save(fig, path, title)


def draw_cdfs(table, path: Path, title: str = '') -> Path:
    """Empirical CDFs of error, saturation and envelope violation over all runs into ``path``.

    PNG.
    """
    c = _columns(table)
    diverged = c['diverged'] > 0
    n = diverged.size
    fig, axes = plt.subplots(1, 3, figsize=(13.5, 3.6), constrained_layout=True)
    for ax, (metric, label, log) in zip(axes, PANELS):
        values = np.sort(np.where(diverged, np.inf, c[metric]))
        finite = values[np.isfinite(values)]
        ax.step(finite, np.arange(1, finite.size + 1) / n, where='post')
        if log:
            ax.set_xscale('log')
            ax.set_title(
                f'{label.replace(" (log10)", "")}\n{int(diverged.sum())} of {n} diverged',
                fontsize=9,
            )
        else:
            ax.set_title(label, fontsize=9)
        ax.set_ylabel('fraction of runs')
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
    return _save(fig, path, title)


def _save(fig, path: Path, title: str) -> Path:
    """Write ``fig`` to ``path`` (PNG) under ``title``, if any; close it; return the path."""
    if title:
        fig.suptitle(title, fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path
