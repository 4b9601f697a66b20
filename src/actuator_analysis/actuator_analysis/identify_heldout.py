# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The identified model as a simulation, and its fit on the held-out blocks (``identify``).

Each held-out block is simulated from the measured state at its start (the filtered angle and
its velocity) with the current the joint held and the load c(t) across it (``identify_load``), by
RK4 with the current held over each sample,
and the simulated angle and velocity are compared with the measured angle and the filtered
angle's velocity: r^2 (1 - residual / total sum of squares about the measured mean) and RMS over
all held-out samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .identify import Fit, Regressors
from .identify_load import held_out_load, knots


def friction(model: str, estimate: np.ndarray, velocity):
    """f(q') of the model [rad/s^2]: Coulomb, Stribeck or drag (the viscous term is theta2's)."""
    out = estimate[2] * np.sign(velocity)
    if model == 'stribeck':
        out = out + estimate[4] * np.exp(-((velocity / estimate[5]) ** 2)) * np.sign(velocity)
    elif model == 'drag':
        out = out + estimate[4] * velocity * np.abs(velocity)
    return out


def acceleration(model: str, estimate: np.ndarray, velocity, current, load=None):
    """Return q'' of the model at a velocity and a current [rad/s^2].

    ``load``: c at that instant (default: the offset, the mean of c(t)).
    """
    return (
        estimate[0] * current
        + estimate[1] * velocity
        - friction(model, estimate, velocity)
        + (estimate[3] if load is None else load)
    )


def simulate(
    model: str,
    estimate: np.ndarray,
    position0: float,
    velocity0: float,
    current_held: np.ndarray,
    dt_s: float,
    substeps: int = 4,
    load: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Angle and velocity at each sample from (q0, v0), current_held[k] over sample k's interval.

    current_held[k] (and load[k], the load c, default the offset) is held over [t_k, t_k+1);
    returns q and v at t_0 .. t_n (n + 1 values).
    """
    n = len(current_held)
    q, v = np.empty(n + 1), np.empty(n + 1)
    q[0], v[0] = position0, velocity0
    h = dt_s / substeps
    loads = np.full(n, estimate[3]) if load is None else load
    for k in range(n):
        x1, x2, u, c = q[k], v[k], current_held[k], loads[k]
        for _ in range(substeps):
            a1 = acceleration(model, estimate, x2, u, c)
            v2 = x2 + 0.5 * h * a1
            a2 = acceleration(model, estimate, v2, u, c)
            v3 = x2 + 0.5 * h * a2
            a3 = acceleration(model, estimate, v3, u, c)
            v4 = x2 + h * a3
            a4 = acceleration(model, estimate, v4, u, c)
            x1 = x1 + h / 6.0 * (x2 + 2.0 * v2 + 2.0 * v3 + v4)
            x2 = x2 + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        q[k + 1], v[k + 1] = x1, x2
    return q, v


@dataclass
class HeldOutFit:
    """Simulated against measured angle and velocity over the held-out blocks."""

    blocks: int
    samples: int
    position_r2: float
    position_rms_rad: float
    velocity_r2: float
    velocity_rms_rad_s: float

    def as_dict(self) -> dict:
        """Plain-dict form."""
        return dict(self.__dict__)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True in ``mask``."""
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def held_out_blocks(reg: Regressors, fit: Fit):
    """Yield (measured q, simulated q, measured v, simulated v) per held-out block."""
    for p, columns in zip(reg.parts, reg.load_columns):
        current = np.asarray(p.record.current_a, dtype=float)
        dt = p.record.dt_s
        knot_times = knots((len(p.record.position_rad) - 1) * dt)
        training_t = p.index[p.training] * dt
        for start, stop in _runs(p.held_out):
            if stop - start < 2:
                continue
            k = p.index[start:stop]
            load = held_out_load(k * dt, knot_times, fit.load_weights[columns], training_t)
            q, v = simulate(
                fit.model,
                fit.estimate,
                p.position[start],
                p.velocity[start],
                current[k[0] + 1 : k[-1] + 1],  # held over [t_k, t_k+1): sample k+1's interval
                dt,
                load=load[:-1],
            )
            yield p.record.position_rad[k], q, p.velocity[start:stop], v


def _r2(measured: np.ndarray, simulated: np.ndarray) -> float:
    """1 - residual sum of squares / total sum of squares about the measured mean."""
    total = float(np.sum((measured - measured.mean()) ** 2))
    return 1.0 - float(np.sum((measured - simulated) ** 2)) / total if total > 0 else float('nan')


def held_out_fit(reg: Regressors, fit: Fit) -> HeldOutFit:
    """r^2 and RMS of the simulated angle and velocity over every held-out block."""
    blocks = list(held_out_blocks(reg, fit))
    if not blocks:
        return HeldOutFit(0, 0, float('nan'), float('nan'), float('nan'), float('nan'))
    qm, qs, vm, vs = (np.concatenate([b[i] for b in blocks]) for i in range(4))
    return HeldOutFit(
        len(blocks),
        int(qm.size),
        _r2(qm, qs),
        float(np.sqrt(np.mean((qm - qs) ** 2))),
        _r2(vm, vs),
        float(np.sqrt(np.mean((vm - vs) ** 2))),
    )
