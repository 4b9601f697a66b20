# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Run metrics of the paper's Tables 5 and 6, shared by the offline simulation and bag analysis.

One function computes every figure from plain arrays, so a run simulated offline and the
same run read back from a bag are judged by the same code.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Optional

import numpy as np

from actuator_core.limits import DIVERGENCE_ERROR_RAD, STEADY_STATE_START_S


@dataclass(frozen=True)
class RunMetrics:
    """Figures of one closed-loop run; every angle in rad, current in A, time in s."""

    duration_s: float
    samples: int
    steady_window_s: tuple[float, float]
    diverged: bool
    max_steady_error_rad: float
    rms_steady_error_rad: float
    rms_error_rad: float
    max_abs_current_a: float
    rms_current_a: float
    saturated_fraction: float
    bounds_kept: bool
    bounds_violations: int
    rms_velocity_estimate_error_rad_s: Optional[float] = None
    rms_disturbance_estimate_error_rad_s2: Optional[float] = None

    def as_dict(self) -> dict:
        """Plain-dict form for JSON output."""
        return asdict(self)


def _rms(x: np.ndarray) -> float:
    """Root mean square of a 1-D array (NaN for an empty one)."""
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else float('nan')


def compute_run_metrics(
    t: np.ndarray,
    error: np.ndarray,
    current: np.ndarray,
    lower_bound: Optional[np.ndarray] = None,
    upper_bound: Optional[np.ndarray] = None,
    saturated: Optional[np.ndarray] = None,
    velocity_estimate_error: Optional[np.ndarray] = None,
    disturbance_estimate_error: Optional[np.ndarray] = None,
    steady_state_start_s: float = STEADY_STATE_START_S,
) -> RunMetrics:
    """Compute the metrics of one run from per-sample arrays of equal length.

    ``error`` is e = y - x1d (eq. 19); ``lower_bound``/``upper_bound`` are -l*rho and h*rho
    (eq. 8) where the run has a prescribed-performance envelope. A run whose error is not
    finite or exceeds ``DIVERGENCE_ERROR_RAD`` is flagged ``diverged``: its error figures are
    then NaN, never a number that could be mistaken for a result.
    """
    t = np.asarray(t, dtype=float)
    error = np.asarray(error, dtype=float)
    current = np.asarray(current, dtype=float)
    if t.ndim != 1 or error.shape != t.shape or current.shape != t.shape:
        raise ValueError('t, error and current must be 1-D arrays of equal length')
    if t.size == 0:
        raise ValueError('a run needs at least one sample')
    steady = t >= steady_state_start_s
    diverged = bool(not np.all(np.isfinite(error)) or np.any(np.abs(error) > DIVERGENCE_ERROR_RAD))
    nan = float('nan')
    if lower_bound is not None and upper_bound is not None:
        inside = (error > np.asarray(lower_bound)) & (error < np.asarray(upper_bound))
        violations = int(np.count_nonzero(~inside))
    else:
        violations = 0
    # NaN: no command in that sample (the law did not run); an infinite one is a figure, kept
    commanded = current[~np.isnan(current)]
    return RunMetrics(
        duration_s=float(t[-1] - t[0]),
        samples=int(t.size),
        steady_window_s=(float(steady_state_start_s), float(t[-1])),
        diverged=diverged,
        max_steady_error_rad=nan
        if diverged or not steady.any()
        else float(np.max(np.abs(error[steady]))),
        rms_steady_error_rad=nan if diverged else _rms(error[steady]),
        rms_error_rad=nan if diverged else _rms(error),
        max_abs_current_a=float(np.max(np.abs(commanded))) if commanded.size else nan,
        rms_current_a=_rms(commanded),
        saturated_fraction=float(np.mean(saturated)) if saturated is not None else 0.0,
        bounds_kept=(not diverged) and violations == 0,
        bounds_violations=violations,
        rms_velocity_estimate_error_rad_s=(
            None
            if velocity_estimate_error is None
            else _rms(np.asarray(velocity_estimate_error, dtype=float))
        ),
        rms_disturbance_estimate_error_rad_s2=(
            None
            if disturbance_estimate_error is None
            else _rms(np.asarray(disturbance_estimate_error, dtype=float))
        ),
    )
