# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Identify the joint's model from its angle and the current it held: theta1, theta2, friction.

Model (paper eq. (2), with the losses gathered into a friction curve per inertia):
    q'' = theta1 i + theta2 q' - f(q') + c
theta1 = k_t/(J N) [rad/s^2/A] as in eq. (2)-(3); theta2 [1/s] is all of the joint's viscous
friction per inertia (the motor's k_b/J of eq. (3), the oil's stirring loss of eq. (6), the
seal's viscous part): from angle and current these cannot be told apart, and the observer and
the law need their sum. f [rad/s^2] is one of ``FRICTION_MODELS``: Coulomb fc sign(q');
Stribeck (fc + fs exp(-(q'/vs)^2)) sign(q'); drag fc sign(q') + fd q'|q'| (a friction that grows
faster than linearly with speed, as an oil-filled seal's). c(t) [rad/s^2] is the load per inertia,
let vary slowly with time (``identify_load``: piecewise linear, knots every 0.5 s) and projected
out of the fit; its mean is reported as the offset c. Only
these per-inertia figures are identifiable: J and k_t separately are not (scaling both leaves
every measured signal unchanged), and the observer's b0 = theta1n and the law need no more.

Estimator (equation error on zero-phase filtered signals). Per contiguous record of a uniform
sample grid, the angle y and the current the joint held over the interval before each sample
are low-passed forward and backward (Butterworth, ``FILTER_ORDER``, ``FILTER_CUTOFF_HZ``: above
the excitation's band, below where the encoder's quantisation dominates a second derivative);
the acceleration and velocity are central differences of the filtered angle, the current is
taken at the sample instants (the mean of the two intervals around each, what a second
difference of a held input sees) and filtered alike, and so are the friction regressors (of the
filtered velocity). The same linear filter on both sides keeps the model's relation. Rows are
dropped within ``EDGE_S`` of a record's ends (filter transients), where the controller reported
the current at its limit, and within the filter's reach ``GUARD_S`` of a velocity reversal (where
the joint may stick and the filtered sign smears the friction's step).

Split: each record is cut into blocks of ``BLOCK_S``; every ``HELD_OUT_EVERY``-th block is held
out (never fitted), with the training rows within ``GUARD_S`` of it. ``identify_heldout``
simulates the held-out blocks and compares angle and velocity (r^2, RMS).

Fit: linear least squares with the load's columns projected out (Frisch-Waugh); Stribeck's vs
by separable least squares (the linear terms solved for each vs, vs by a bounded search on its
logarithm). Intervals (95 %): the least-squares Jacobian's bread around a meat of the training
blocks' score sums (cluster-robust with the blocks as clusters, as the filtered residuals are
correlated within a block), a Student t quantile on (blocks - parameters) degrees of freedom,
the load's local weights not counted. Friction model: the one of lowest BIC, counted on the
effective sample count (rows x 2 f_c dt: rows closer than half a filter period are not
independent), among Coulomb + viscous and the candidates whose extra term is significant (its
95 % interval excludes 0; Stribeck's vs inside its search range).

Known limit: on a joint of the model's own family without noise, the Coulomb step at the
reversals leaves a bias in theta1 of 0.02-0.06 % (the filter's reach outlasts ``GUARD_S``), about
the width of such a joint's interval; a longer guard removes it there but, on the suite's plant
(seal friction growing exponentially, eq. (42)), leaves the sweeps' friction to pull theta1 by
0.2-0.4 %, far outside the intervals (measured over 40 offline-drawn joints with the load held
constant: ``GUARD_S`` 0.03 s covered theta1 in all, 0.06 s in 2; with the load c(t) and 0.03 s,
again in all 40). The guard is the one that serves the plant.

Refusals (``RefusedData``, one line with the reason; ``identify_joint`` runs them): non-finite
samples, too little data, the current at its limit in more than
``limits.SATURATED_FRACTION_LIMIT`` of the samples, motion one way only, an acceleration RMS below
``MIN_ACCELERATION_RMS_RAD_S2`` (a constant-speed run, a joint at rest), and a theta1 that is not
positive or whose interval is wider than ``MAX_THETA1_HALF_WIDTH`` of itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, signal, stats

from actuator_core.identified import FRICTION_MODELS

from .identify_load import LoadProjection, filtered_hats

#: Zero-phase low-pass of the angle and current before differentiating.
FILTER_CUTOFF_HZ = 30.0
FILTER_ORDER = 4
#: Samples dropped at each end of a record (the forward-backward filter's transients) [s].
EDGE_S = 0.1
#: Block length of the held-out split and of the interval's clusters [s]; every n-th is held out.
BLOCK_S = 1.0
HELD_OUT_EVERY = 4
#: The zero-phase filter's reach [s]: training samples this close to a held-out block, or to a
#: velocity reversal (|q'| below REVERSAL_SPEED_RAD_S, where the joint may stick and the filtered
#: sign smears the friction's step), are dropped.
GUARD_S = 0.03
REVERSAL_SPEED_RAD_S = 0.2
#: Confidence level of the intervals.
CONFIDENCE = 0.95
#: Refusals: too little data [s], too few blocks, motion one way [share of samples], no
#: acceleration [rad/s^2], theta1 not determined [relative 95 % half-width].
MIN_DURATION_S = 8.0
MIN_TRAINING_BLOCKS = 6
MIN_HELD_OUT_BLOCKS = 2
MIN_DIRECTION_SHARE = 0.05
MOVING_SPEED_RAD_S = 0.05
MIN_ACCELERATION_RMS_RAD_S2 = 5.0
MAX_THETA1_HALF_WIDTH = 0.10
#: Stribeck velocity search range [rad/s].
STRIBECK_VELOCITY_RAD_S = (0.01, 5.0)
#: What the tool must say: which figures a run of angle and current can give.
IDENTIFIABLE = (
    'from angle and current only theta1 = k_t/(J N) and the friction per inertia (theta2, '
    'Coulomb, Stribeck, offset) are identifiable, not J, k_t or k_b separately; theta2 is all '
    'of the viscous friction (motor, oil stirring, seal)'
)
#: Parameter names per friction model, in the order of the estimate vector.
PARAMETERS = {
    'coulomb_viscous': ('theta1', 'theta2', 'coulomb_rad_s2', 'offset_rad_s2'),
    'stribeck': (
        'theta1',
        'theta2',
        'coulomb_rad_s2',
        'offset_rad_s2',
        'stribeck_rad_s2',
        'stribeck_velocity_rad_s',
    ),
    'drag': ('theta1', 'theta2', 'coulomb_rad_s2', 'offset_rad_s2', 'drag_per_rad'),
}
UNITS = {
    'theta1': 'rad/s^2/A',
    'theta2': '1/s',
    'coulomb_rad_s2': 'rad/s^2',
    'offset_rad_s2': 'rad/s^2',
    'stribeck_rad_s2': 'rad/s^2',
    'stribeck_velocity_rad_s': 'rad/s',
    'drag_per_rad': '1/rad',
}


class RefusedData(ValueError):
    """The data cannot identify the model; the message is the one-line reason."""


@dataclass(frozen=True)
class Record:
    """One contiguous stretch of samples on a uniform grid.

    ``current_a[k]`` is the current held over the interval before sample k.
    """

    dt_s: float
    position_rad: np.ndarray
    current_a: np.ndarray
    at_limit: np.ndarray  # bool per sample: the controller reported the current at its limit
    name: str = ''


@dataclass
class Prepared:
    """One record's filtered signals at its kept samples k (``index``), with split and block."""

    record: Record
    index: np.ndarray  # sample numbers k of the rows (1 <= k <= n - 2, off the edges)
    position: np.ndarray  # filtered angle at k
    velocity: np.ndarray  # its central difference
    acceleration: np.ndarray  # its second difference
    current: np.ndarray  # filtered current at the instant t_k
    sign: np.ndarray  # filtered sign of the velocity
    block: np.ndarray  # block id (global over the records)
    training: np.ndarray  # bool
    held_out: np.ndarray  # bool
    sos: np.ndarray
    record_velocity: np.ndarray  # the filtered angle's velocity at every sample of the record
    load: np.ndarray  # the load's hats at the rows, filtered (identify_load)


@dataclass
class Regressors:
    """The fit's rows of every record, stacked."""

    parts: list[Prepared]
    dt_s: float

    def stack(self, name: str) -> np.ndarray:
        """One field of every record, concatenated."""
        return np.concatenate([getattr(p, name) for p in self.parts])

    def __post_init__(self) -> None:
        """Stack the columns the fit reads; the load's hats block-diagonal (one set per record)."""
        self.velocity = self.stack('velocity')
        self.acceleration = self.stack('acceleration')
        self.current = self.stack('current')
        self.sign = self.stack('sign')
        self.block = self.stack('block')
        self.training = self.stack('training')
        self.load = np.zeros((self.velocity.size, sum(p.load.shape[1] for p in self.parts)))
        self.load_columns, row, column = [], 0, 0
        for p in self.parts:
            rows, columns = p.load.shape
            self.load[row : row + rows, column : column + columns] = p.load
            self.load_columns.append(slice(column, column + columns))
            row, column = row + rows, column + columns


@dataclass
class Fit:
    """One friction model's estimates, covariance and figures on the training rows."""

    model: str
    estimate: np.ndarray
    covariance: np.ndarray
    half_width: np.ndarray
    rss: float
    rows: int
    blocks: int
    bic: float
    load_weights: np.ndarray  # of every hat of the load c(t) (identify_load)

    def as_dict(self) -> dict:
        """Estimates with their 95 % intervals, by name."""
        return {
            name: {
                'value': float(v),
                'low': float(v - h),
                'high': float(v + h),
                'unit': UNITS[name],
            }
            for name, v, h in zip(PARAMETERS[self.model], self.estimate, self.half_width)
        }


def _filter(dt_s: float, cutoff_hz: float):
    """Second-order sections of the zero-phase low-pass."""
    nyquist = 0.5 / dt_s
    if not 0.0 < cutoff_hz < nyquist:
        raise RefusedData(
            f'filter cutoff {cutoff_hz:g} Hz must be below the Nyquist frequency {nyquist:g} Hz'
        )
    return signal.butter(FILTER_ORDER, cutoff_hz, fs=1.0 / dt_s, output='sos')


def lowpass(x: np.ndarray, dt_s: float, cutoff_hz: float = FILTER_CUTOFF_HZ) -> np.ndarray:
    """Zero-phase low-pass of the estimator (Butterworth, forward and backward)."""
    return signal.sosfiltfilt(_filter(dt_s, cutoff_hz), x)


def check_records(records: list[Record]) -> None:
    """Refuse records with non-finite samples or a sample time that differs between them."""
    if not records:
        raise RefusedData('no samples to identify from')
    for r in records:
        bad = np.count_nonzero(~np.isfinite(r.position_rad)) + np.count_nonzero(
            ~np.isfinite(r.current_a)
        )
        if bad:
            raise RefusedData(
                f'{r.name or "a record"}: {bad} angle or current samples are not finite (NaN or '
                'inf): the joint or the bag reported no value there'
            )
    periods = {round(r.dt_s, 9) for r in records}
    if len(periods) > 1:
        raise RefusedData(f'the records have different sample times: {sorted(periods)} s')


def prepare(record: Record, sos: np.ndarray, first_block: int = 0) -> Prepared | None:
    """Filter one record and mark its rows (None when it is too short for one block)."""
    dt = record.dt_s
    edge = int(round(EDGE_S / dt))
    per_block = int(round(BLOCK_S / dt))
    guard = int(round(GUARD_S / dt))
    n = len(record.position_rad)
    if n < 2 * edge + per_block:
        return None
    yf = signal.sosfiltfilt(sos, np.asarray(record.position_rad, dtype=float))
    current = np.asarray(record.current_a, dtype=float)
    i_mid = 0.5 * (current[:-1] + current[1:])  # at t_k: the intervals before and after it
    k = np.arange(edge, n - edge)
    vel_all = np.gradient(yf, dt)
    acc = (yf[k + 1] - 2.0 * yf[k] + yf[k - 1]) / (dt * dt)
    vel = (yf[k + 1] - yf[k - 1]) / (2.0 * dt)
    cur = signal.sosfiltfilt(sos, i_mid)[k]
    sgn = signal.sosfiltfilt(sos, np.sign(vel_all))[k]
    window = np.ones(2 * guard + 1)
    at_limit = np.convolve(np.asarray(record.at_limit, bool), window, 'same')[k] > 0
    block = (k - edge) // per_block
    held = (block % HELD_OUT_EVERY) == HELD_OUT_EVERY - 1
    near_held = np.convolve(held, window, 'same') > 0
    near_reversal = np.convolve(np.abs(vel) < REVERSAL_SPEED_RAD_S, window, 'same') > 0
    return Prepared(
        record, k, yf[k], vel, acc, cur, sgn, block + first_block,
        ~near_held & ~at_limit & ~near_reversal,
        held & ~at_limit, sos, vel_all, filtered_hats(n, dt, sos, k),
    )  # fmt: skip


def regressors(records: list[Record], cutoff_hz: float = FILTER_CUTOFF_HZ) -> Regressors:
    """Filter each record and stack its rows; mark the training and the held-out ones."""
    check_records(records)
    dt = records[0].dt_s
    sos = _filter(dt, cutoff_hz)
    parts, first = [], 0
    for r in records:
        p = prepare(r, sos, first)
        if p is not None:
            parts.append(p)
            first = int(p.block.max()) + 1
    if not parts:
        raise RefusedData(
            f'no record is long enough: each needs at least {2 * EDGE_S + BLOCK_S:g} s of '
            'contiguous samples'
        )
    return Regressors(parts, dt)


def _feature(reg: Regressors, function) -> np.ndarray:
    """Return g(q') per row: g of each record's velocity, filtered like the other columns."""
    return np.concatenate(
        [signal.sosfiltfilt(p.sos, function(p.record_velocity))[p.index] for p in reg.parts]
    )


def _stribeck_shape(velocity_scale: float):
    """g(v) = exp(-(v/vs)^2) sign(v)."""
    return lambda v: np.exp(-((v / velocity_scale) ** 2)) * np.sign(v)


def design_matrix(reg: Regressors, model: str, stribeck_velocity: float = 1.0) -> np.ndarray:
    """Columns multiplying theta1, theta2, fc and the model's extra friction term (c: the load)."""
    cols = [reg.current, reg.velocity, -reg.sign]
    if model == 'stribeck':
        cols.append(-_feature(reg, _stribeck_shape(stribeck_velocity)))
    elif model == 'drag':
        cols.append(-_feature(reg, lambda v: v * np.abs(v)))
    elif model != 'coulomb_viscous':
        raise ValueError(f'friction model must be one of {", ".join(FRICTION_MODELS)}: {model!r}')
    return np.column_stack(cols)


def _covariance(
    jac: np.ndarray, residual: np.ndarray, blocks: np.ndarray, dof_parameters: int
) -> tuple:
    """Cluster-robust covariance (blocks as clusters) and its t quantile.

    Degrees of freedom: blocks - ``dof_parameters``, the parameters of interest (the load's
    local weights are nuisance parameters, each of one block or two).
    """
    bread = np.linalg.pinv(jac.T @ jac)
    ids, where = np.unique(blocks, return_inverse=True)
    scores = np.zeros((len(ids), jac.shape[1]))
    np.add.at(scores, where, jac * residual[:, None])
    dof = max(len(ids) - dof_parameters, 1)
    meat = scores.T @ scores * (len(ids) / dof)
    return bread @ meat @ bread, float(stats.t.ppf(0.5 + 0.5 * CONFIDENCE, dof))


def _bic(rss: float, rows: int, parameters: int, dt_s: float, cutoff_hz: float) -> float:
    """BIC on the effective sample count rows x 2 f_c dt."""
    n_eff = max(rows * 2.0 * cutoff_hz * dt_s, parameters + 1.0)
    return n_eff * math.log(rss / rows) + parameters * math.log(n_eff)


def _stribeck_estimate(reg: Regressors, y: np.ndarray, rows: np.ndarray, project):
    """Separable least squares: for each vs the linear terms, vs by a bounded search on log vs.

    The load projected out. Returns (theta1, theta2, fc, fs, vs) and d(model)/d(parameters)
    at the training rows (unprojected).
    """
    low, high = STRIBECK_VELOCITY_RAD_S
    fixed, py = project(design_matrix(reg, 'coulomb_viscous')[rows]), project(y)

    def solve(log_vs: float) -> tuple[float, np.ndarray]:
        column = project(-_feature(reg, _stribeck_shape(math.exp(log_vs)))[rows])
        x = np.column_stack((fixed, column))
        beta = np.linalg.lstsq(x, py, rcond=None)[0]
        rest = py - x @ beta
        return float(rest @ rest), beta

    best = optimize.minimize_scalar(
        lambda z: solve(z)[0],
        bounds=(math.log(low), math.log(high)),
        method='bounded',
        options={'xatol': 1e-4},
    )
    vs = math.exp(best.x)
    estimate = np.append(solve(best.x)[1], vs)
    x = design_matrix(reg, 'stribeck', vs)[rows]
    step = 1e-6 * vs
    slope = (
        design_matrix(reg, 'stribeck', vs + step)[rows][:, -1]
        - design_matrix(reg, 'stribeck', vs - step)[rows][:, -1]
    ) / (2.0 * step)
    return estimate, np.column_stack((x, estimate[3] * slope))


def fit_model(reg: Regressors, model: str, cutoff_hz: float = FILTER_CUTOFF_HZ) -> Fit:
    """Least squares of one friction model on the training rows, with its intervals.

    The load c(t) is projected out (``identify_load``); the estimate vector holds the
    parameters in ``PARAMETERS`` order, the offset c being the mean of c(t).
    """
    rows = reg.training
    y = reg.acceleration[rows]
    project = LoadProjection(reg.load[rows])
    if model == 'stribeck':
        main, jac = _stribeck_estimate(reg, y, rows, project)
        fitted = design_matrix(reg, model, main[-1])[rows] @ main[:-1]
    else:
        jac = design_matrix(reg, model)[rows]
        main = np.linalg.lstsq(project(jac), project(y), rcond=None)[0]
        fitted = jac @ main
    weights = project.weights(y - fitted)
    basis = project.basis
    residual = y - fitted - basis @ weights[project.keep]
    whole = np.column_stack((jac, basis))
    cov_all, quantile = _covariance(whole, residual, reg.block[rows], dof_parameters=len(main))
    # (main, w) -> (theta1, theta2, fc, offset = mean c(t) over the training rows, extra...)
    p = len(main)
    to_reported = np.zeros((p + 1, whole.shape[1]))
    to_reported[:3, :3] = np.eye(3)
    to_reported[3, p:] = basis.mean(axis=0)
    to_reported[4:, 3:p] = np.eye(p - 3)
    cov = to_reported @ cov_all @ to_reported.T
    estimate = to_reported @ np.concatenate((main, weights[project.keep]))
    half = quantile * np.sqrt(np.maximum(np.diag(cov), 0.0))
    rss = float(residual @ residual)
    return Fit(
        model,
        estimate,
        cov,
        half,
        rss,
        int(y.size),
        len(np.unique(reg.block[rows])),
        _bic(rss, int(y.size), whole.shape[1], reg.dt_s, cutoff_hz),
        weights,
    )


def load_at_rows(reg: Regressors, fit: Fit) -> np.ndarray:
    """c(t) of a fit at every row (filtered like the columns)."""
    return reg.load @ fit.load_weights


def supported(fit: Fit) -> bool:
    """Whether a fit's extra friction term is significant (and vs inside its search range)."""
    if fit.model == 'coulomb_viscous':
        return True
    if abs(fit.estimate[4]) <= fit.half_width[4]:
        return False
    if fit.model == 'stribeck':
        low, high = STRIBECK_VELOCITY_RAD_S
        return bool(low * 1.01 < fit.estimate[5] < high * 0.99)
    return True


def choose_model(fits: dict[str, Fit]) -> Fit:
    """Return the fit of lowest BIC among Coulomb + viscous and the supported candidates."""
    return min((f for f in fits.values() if supported(f)), key=lambda f: f.bic)
