# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The identified model's load c(t): piecewise linear in time, a nuisance the fit projects out.

A joint's load is rarely constant: the paper's external torque (40) swings by half its mean at
0.25 Hz, and the controller's current follows it. Fitted as a constant, such a load leaves a slow
current without its acceleration and pulls theta1 down (by a third on the excitation scenario at
1000 m). So c(t) = sum_j w_j hat_j(t), hats of half-width ``LOAD_KNOT_S`` on knots every
``LOAD_KNOT_S`` from each record's start, filtered like the other columns: loads slower than
about 1 / (2 LOAD_KNOT_S) are absorbed, and theta1, theta2 and the friction are fitted on what is
faster (the Frisch-Waugh projection: the same estimates as the joint fit, at the cost of the
slow content). The reported offset is the mean of c(t); a held-out block, whose own hats have no
training samples, takes c(t) interpolated linearly between its neighbours' training samples.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

#: Knot spacing of the load c(t) [s].
LOAD_KNOT_S = 0.5
#: A hat whose filtered column stays below this at every training sample is left out.
SUPPORT = 1e-3


def knots(duration_s: float) -> np.ndarray:
    """Knot times of a record lasting ``duration_s`` [s]."""
    return np.arange(0.0, duration_s + LOAD_KNOT_S, LOAD_KNOT_S)


def hats(t: np.ndarray, knot_times: np.ndarray) -> np.ndarray:
    """hat_j(t): 1 at knot j, 0 from the next knots on, linear between (rows t, columns j)."""
    return np.clip(1.0 - np.abs(t[:, None] - knot_times[None, :]) / LOAD_KNOT_S, 0.0, None)


def filtered_hats(n: int, dt_s: float, sos: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Return the hats of a record of ``n`` samples, filtered like its columns, at ``index``."""
    t = np.arange(n) * dt_s
    return signal.sosfiltfilt(sos, hats(t, knots(t[-1])), axis=0)[index]


class LoadProjection:
    """Projects the load's columns out of the training rows: P v = v - Q (Q' v)."""

    def __init__(self, basis: np.ndarray):
        """``basis``: the load's columns at the training rows."""
        self.keep = np.max(np.abs(basis), axis=0) > SUPPORT
        self.basis = basis[:, self.keep]
        self.q, _ = np.linalg.qr(self.basis)

    def __call__(self, v: np.ndarray) -> np.ndarray:
        """Return v with the load's columns projected out (a vector or a matrix's columns)."""
        return v - self.q @ (self.q.T @ v)

    def weights(self, rest: np.ndarray) -> np.ndarray:
        """Return the load weights (all hats, 0 for those left out) that fit ``rest`` best."""
        out = np.zeros(self.keep.size)
        out[self.keep] = np.linalg.lstsq(self.basis, rest, rcond=None)[0]
        return out


def held_out_load(
    t: np.ndarray, knot_times: np.ndarray, weights: np.ndarray, training_t: np.ndarray
) -> np.ndarray:
    """Return c(t) at the samples ``t`` of a held-out block, linear between its neighbours.

    The neighbours are the nearest training samples before and after it (the one there is when
    the block ends a record).
    """
    before, after = training_t[training_t < t[0]], training_t[training_t > t[-1]]
    ends = [x for x in (before[-1:], after[:1]) if x.size]
    if not ends:
        return np.zeros_like(t)
    at = np.concatenate(ends)
    value = hats(at, knot_times) @ weights
    return np.interp(t, at, value) if at.size == 2 else np.full_like(t, value[0])
