# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The figures of ``bag_identify --out``: the held-out fit and the friction curve, as PNG files.

identify_held_out.png: measured and simulated velocity over the first held-out blocks (each
simulated from its measured start), the residual below. identify_friction.png: what the data
says the velocity-dependent acceleration is, q'' - theta1 i - c(t) over the training samples
against q', with the model's theta2 q' - f(q') through it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .identify import load_at_rows
from .identify_heldout import friction, held_out_blocks
from .identify_joint import Identification

#: Held-out blocks drawn, and training points scattered (an even subsample).
BLOCKS_DRAWN = 3
POINTS_DRAWN = 4000


def draw_identification(result: Identification, folder: Path) -> list[Path]:
    """Write the two figures into ``folder``; return their paths."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    reg, model, estimate = result.regressors, result.model, result.chosen.estimate
    dt = reg.dt_s
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    start = 0.0
    for i, (_, _, measured, simulated) in enumerate(held_out_blocks(reg, result.chosen)):
        if i == BLOCKS_DRAWN:
            break
        t = start + dt * np.arange(measured.size)
        top.plot(t, measured, 'k', lw=1.0, label='measured' if i == 0 else None)
        top.plot(t, simulated, 'C1--', lw=1.0, label='simulated' if i == 0 else None)
        bottom.plot(t, simulated - measured, 'C1', lw=0.8)
        start = t[-1] + 0.2
    h = result.held_out
    top.set(
        ylabel='velocity [rad/s]',
        title=f'held-out blocks, each simulated from its start: velocity r^2 {h.velocity_r2:.4f}, '
        f'RMS {h.velocity_rms_rad_s:.3g} rad/s',
    )
    top.legend(loc='upper right', fontsize=8)
    bottom.set(xlabel='time in the blocks drawn [s]', ylabel='simulated - measured [rad/s]')
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    paths = [folder / 'identify_held_out.png']
    fig.savefig(paths[0], dpi=110)
    plt.close(fig)

    rows = np.flatnonzero(reg.training)
    rows = rows[:: max(1, rows.size // POINTS_DRAWN)]
    v = reg.velocity[rows]
    load = load_at_rows(reg, result.chosen)[rows]
    seen = reg.acceleration[rows] - estimate[0] * reg.current[rows] - load
    grid = np.linspace(v.min(), v.max(), 400)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(v, seen, '.', ms=2, color='0.5', label="q'' - theta1 i - c(t) (training samples)")
    ax.plot(grid, estimate[1] * grid - friction(model, estimate, grid), 'C1', lw=1.5,
            label=f"theta2 q' - f(q'), {model}")  # fmt: skip
    ax.set(
        xlabel="velocity q' [rad/s]",
        ylabel='velocity-dependent acceleration [rad/s^2]',
        title=f'friction per inertia: theta2 {estimate[1]:.3g} 1/s, Coulomb {estimate[2]:.3g} '
        'rad/s^2',
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    paths.append(folder / 'identify_friction.png')
    fig.savefig(paths[1], dpi=110)
    plt.close(fig)
    return paths
