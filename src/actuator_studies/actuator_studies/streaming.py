# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Run metrics of a vectorised batch computed while it runs: no per-sample trace is kept.

``StreamingMetrics.add`` takes one sample of every run of a batch (the ``ClosedLoop.step`` row)
and updates running sums, maxima and counts; ``freeze`` keeps the figures of the runs cut at
that sample; ``columns`` turns them into the figures of ``RunMetrics`` (Tables 5-6), with the
definitions ``trace_metrics`` applies to a recorded trace: a latched sample's error counts as
non-finite, bounds that are not finite on every sample fall back to Table 4's envelope (8),
RMS = sqrt(sum of squares / samples). A run's figures cover its samples up to and including the
one it was cut at. Memory is O(batch): a batch of 10 000 runs of any duration needs a few MB.
The common case (every current finite, no latched run, bounds finite) takes about 25 array
operations per sample; the others are handled exactly on slower paths.
"""

from __future__ import annotations

import numpy as np

from actuator_controller.ppf import PrescribedPerformance
from actuator_core.limits import DIVERGENCE_ERROR_RAD, STEADY_STATE_START_S
from actuator_core.status import Status

#: Running per-run sums and extrema, frozen for a run when it is cut.
_SUMS = (
    'samples',
    'steady_samples',
    'sq_error',
    'sq_steady_error',
    'max_abs_error',  # NaN-propagating: decides the trace's divergence
    'max_steady',
    'sq_current',
    'finite_current',
    'max_current',
    'saturated',
    'inside_own',
    'own_finite_samples',
    'inside_table4',
    'inside_paper',
    'sq_velocity_error',
    'sq_disturbance_error',
)


class StreamingMetrics:
    """Running per-run sums of one batch of n runs (eq. (8) envelope counts included)."""

    def __init__(self, n: int, paper_ppf, steady_state_start_s: float = STEADY_STATE_START_S):
        """Zero every sum; ``paper_ppf`` is the run's envelope (8) from t = 0, restarts ignored."""
        self.n, self.paper_ppf, self.steady_start = n, paper_ppf, steady_state_start_s
        self.table4 = PrescribedPerformance()
        self.same_envelope = paper_ppf == self.table4
        self.acc = {k: np.zeros(n) for k in _SUMS}
        self.acc['max_steady'][:] = -np.inf
        self.acc['max_current'][:] = -np.inf
        self.count = 0  # samples added (before freezing: every run's count)
        self.steady_count = 0
        self.t_first = np.nan
        self.t_last = np.nan
        self.frozen = {k: np.full(n, np.nan) for k in _SUMS}
        self.frozen_t_last = np.full(n, np.nan)
        self.is_frozen = np.zeros(n, dtype=bool)

    def add(self, row: dict) -> None:
        """Add sample ``row`` to every run (cut runs are frozen, later samples do not count)."""
        acc, n = self.acc, self.n
        t = float(row['t_s'])
        if self.count == 0:
            self.t_first = t
        self.t_last = t
        self.count += 1
        raw = np.asarray(row['error_rad'], dtype=float)
        latched = np.asarray(row['status']) == Status.LATCHED
        any_latched = bool(latched.any())
        error = np.where(latched, np.nan, raw) if any_latched else raw
        sq = error * error
        acc['sq_error'] += sq
        abs_error = np.abs(error)
        np.maximum(acc['max_abs_error'], abs_error, out=acc['max_abs_error'])
        if t >= self.steady_start:
            self.steady_count += 1
            acc['sq_steady_error'] += sq
            np.fmax(acc['max_steady'], abs_error, out=acc['max_steady'])
        current = np.broadcast_to(np.asarray(row['current_a'], dtype=float), (n,))
        finite = np.isfinite(current)
        if finite.all():
            acc['finite_current'] += 1.0
            acc['sq_current'] += current * current
            np.fmax(acc['max_current'], np.abs(current), out=acc['max_current'])
        else:
            acc['finite_current'] += finite
            acc['sq_current'] += np.where(finite, current * current, 0.0)
            np.fmax(
                acc['max_current'],
                np.where(finite, np.abs(current), -np.inf),
                out=acc['max_current'],
            )
        acc['saturated'] += np.asarray(row['saturated'], dtype=bool)
        lower, upper = row['lower_bound_rad'], row['upper_bound_rad']
        own_finite = np.isfinite(lower)
        if own_finite.all():
            acc['own_finite_samples'] += 1.0
        else:
            acc['own_finite_samples'] += own_finite
        acc['inside_own'] += (error > lower) & (error < upper)
        lo, hi = self.paper_ppf.bounds(t)
        inside_paper = (raw > lo) & (raw < hi)
        acc['inside_paper'] += inside_paper
        if self.same_envelope and not any_latched:  # same bounds, same error: same count
            acc['inside_table4'] += inside_paper
        else:
            lo4, hi4 = self.table4.bounds(t)
            acc['inside_table4'] += (error > lo4) & (error < hi4)
        for key, est, true in (
            ('sq_velocity_error', 'x2_hat_rad_s', 'true_velocity_rad_s'),
            ('sq_disturbance_error', 'x3_hat_rad_s2', 'true_disturbance_rad_s2'),
        ):
            d = np.asarray(row[est], dtype=float) - np.asarray(row[true], dtype=float)
            acc[key] += d * d

    def freeze(self, runs: np.ndarray) -> None:
        """Keep the figures of ``runs`` (a boolean mask) as they are after the last sample."""
        take = runs & ~self.is_frozen
        if not take.any():
            return
        for k in _SUMS:
            self.frozen[k][take] = np.broadcast_to(self.acc[k], (self.n,))[take]
        self.frozen['samples'][take] = self.count
        self.frozen['steady_samples'][take] = self.steady_count
        self.frozen_t_last[take] = self.t_last
        self.is_frozen |= take

    def columns(self, full_samples: int) -> dict[str, np.ndarray]:
        """Metric columns (runner.METRIC_COLUMNS) of every run; a run cut early is diverged."""
        acc = dict(self.acc)
        acc['samples'] = np.full(self.n, float(self.count))
        acc['steady_samples'] = np.full(self.n, float(self.steady_count))
        fz = self.is_frozen
        v = {k: np.where(fz, self.frozen[k], acc[k]) for k in _SUMS}
        t_last = np.where(fz, self.frozen_t_last, self.t_last)
        samples = v['samples']
        diverged_trace = ~(v['max_abs_error'] <= DIVERGENCE_ERROR_RAD)

        def rms(key: str, count: np.ndarray) -> np.ndarray:
            with np.errstate(all='ignore'):
                return np.where(count > 0, np.sqrt(v[key] / np.maximum(count, 1)), np.nan)

        own_everywhere = v['own_finite_samples'] == samples
        violations = samples - np.where(own_everywhere, v['inside_own'], v['inside_table4'])
        steady = v['steady_samples'] > 0
        nan = np.full(self.n, np.nan)
        paper_violations = samples - v['inside_paper']
        return {
            'duration_s': t_last - self.t_first,
            'samples': samples.astype(int),
            'diverged': diverged_trace | (samples < full_samples),
            'max_steady_error_rad': np.where(diverged_trace | ~steady, nan, v['max_steady']),
            'rms_steady_error_rad': np.where(
                diverged_trace, nan, rms('sq_steady_error', v['steady_samples'])
            ),
            'rms_error_rad': np.where(diverged_trace, nan, rms('sq_error', samples)),
            'max_abs_current_a': np.where(v['finite_current'] > 0, v['max_current'], nan),
            'rms_current_a': rms('sq_current', v['finite_current']),
            'saturated_fraction': v['saturated'] / samples,
            'bounds_kept': ~diverged_trace & (violations == 0),
            'bounds_violations': violations.astype(int),
            'rms_velocity_estimate_error_rad_s': rms('sq_velocity_error', samples),
            'rms_disturbance_estimate_error_rad_s2': rms('sq_disturbance_error', samples),
            'steady_window_start_s': np.full(self.n, float(self.steady_start)),
            'steady_window_end_s': t_last,
            'saturated_samples': v['saturated'].astype(int),
            'bounds_violation_fraction': violations / samples,
            'paper_envelope_violations': paper_violations.astype(int),
            'paper_envelope_violation_fraction': paper_violations / samples,
        }
