# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Batched runs of a study: the design table cut into chunks, each chunk one vectorised ClosedLoop.

A chunk is ``batch`` consecutive runs of the table, run as ClosedLoop(scenario, batch=n) with
every varied quantity an array (the model, observer and controller work elementwise).
Quantities that cannot differ inside one batch (``Quantity.vector`` False, e.g. the
envelope's ppf.* or dt) split a chunk into groups of equal values, each its own batch.

Each run is judged exactly as ``offline_sim`` judges a single run: the trace is cut after the
first sample whose angle is not finite or whose error exceeds DIVERGENCE_ERROR_RAD (as
``ClosedLoop.run`` cuts it), a cut run counts as diverged, and ``trace_metrics`` gives every
figure of RunMetrics. One row per run: the run index, its seed, every varied quantity, the
metrics, and the saturated and out-of-envelope sample counts.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from actuator_controller.ppf import PrescribedPerformance
from actuator_core.limits import DIVERGENCE_ERROR_RAD
from actuator_core.metrics import RunMetrics
from actuator_core.status import Status
from actuator_sim.loop import ClosedLoop
from actuator_studies.space import BaseScenario, build_scenario, quantities, run_seeds
from actuator_studies.streaming import StreamingMetrics

#: Memory of a task's worker before its batch [bytes] (Python, numpy and the project's modules).
TASK_BASE_MEMORY_BYTES = 300 * 1024 * 1024
#: Memory per run of a vectorised batch [bytes]: loop state and running sums (about 2.3 KiB
#: measured at 8192 runs), with headroom.
TASK_MEMORY_PER_RUN_BYTES = 16 * 1024
#: Metric columns of a row, in order (steady_window_s becomes two columns).
METRIC_COLUMNS = tuple(
    f.name for f in dataclasses.fields(RunMetrics) if f.name != 'steady_window_s'
) + (
    'steady_window_start_s',
    'steady_window_end_s',
    'saturated_samples',
    'bounds_violation_fraction',
    'paper_envelope_violations',
    'paper_envelope_violation_fraction',
)


@dataclass(frozen=True)
class SweepSpec:
    """A whole study.

    Base scenario, the design table (name -> one value per run), batch size and seed.
    """

    base: BaseScenario
    table: dict
    batch: int  # runs per vectorised ClosedLoop
    seed: int
    chunk_runs: int = 0  # runs per chunk (one task, one file); 0: one batch

    @property
    def chunk_size(self) -> int:
        """Runs per chunk."""
        return self.chunk_runs or self.batch

    @property
    def runs(self) -> int:
        """Number of runs in the table."""
        return len(next(iter(self.table.values()))) if self.table else 1

    @property
    def chunks(self) -> int:
        """Number of chunks of ``batch`` runs."""
        return -(-self.runs // self.chunk_size)

    def chunk_indices(self, chunk: int) -> np.ndarray:
        """Run indices of chunk ``chunk``."""
        size = self.chunk_size
        return np.arange(chunk * size, min((chunk + 1) * size, self.runs))


def run_batch(
    base: BaseScenario, values: dict[str, np.ndarray], seeds: np.ndarray
) -> dict[str, np.ndarray]:
    """Metric columns (METRIC_COLUMNS) of n runs at once, computed while they run.

    ``values`` holds n values per varied quantity. A run is cut after the first sample whose
    measured angle is not finite, whose error exceeds DIVERGENCE_ERROR_RAD or whose controller
    latched (as ``ClosedLoop.run`` cuts a single run); the batch stops when every run is cut.
    """
    n = len(seeds)
    scenario = build_scenario(base, values, seeds=seeds, name='batch')
    loop = ClosedLoop(scenario, batch=n)
    samples = scenario.samples
    ppf = getattr(scenario.gains, 'ppf', None) or PrescribedPerformance()
    stream = StreamingMetrics(n, ppf)
    measured_bad = np.zeros(n, dtype=bool)
    with np.errstate(all='ignore'):
        for _ in range(samples):
            row = loop.step()
            stream.add(row)
            bad = (
                ~np.isfinite(row['measured_position_rad'])
                | (np.abs(row['error_rad']) > DIVERGENCE_ERROR_RAD)
                | (np.asarray(row['status']) == Status.LATCHED)
            )
            if (bad & ~measured_bad).any():
                stream.freeze(bad)
                measured_bad |= bad
                if measured_bad.all():
                    break
        return stream.columns(samples)


def task_memory_bytes(spec: 'SweepSpec') -> int:
    """Memory a chunk task declares to Ray [bytes]: interpreter and numpy, plus per-run state."""
    return TASK_BASE_MEMORY_BYTES + TASK_MEMORY_PER_RUN_BYTES * min(spec.batch, spec.chunk_size)


def paper_envelope_violations(t_s: np.ndarray, error_rad: np.ndarray, gains) -> int:
    """Count the samples with e outside (-l rho(t), h rho(t)) of (8) from t = 0, restarts ignored.

    Table 4's PPF without one.
    """
    ppf = getattr(gains, 'ppf', None) or PrescribedPerformance()
    lower, upper = ppf.bounds(t_s)
    return int(np.count_nonzero(~((error_rad > lower) & (error_rad < upper))))


def metrics_row(metrics: RunMetrics, paper_violations: int = 0) -> dict[str, Any]:
    """Return the metric columns of one run."""
    row = {k: v for k, v in metrics.as_dict().items() if k != 'steady_window_s'}
    row['steady_window_start_s'], row['steady_window_end_s'] = metrics.steady_window_s
    row['saturated_samples'] = int(round(metrics.saturated_fraction * metrics.samples))
    row['bounds_violation_fraction'] = metrics.bounds_violations / metrics.samples
    row['paper_envelope_violations'] = paper_violations
    row['paper_envelope_violation_fraction'] = paper_violations / metrics.samples
    for key in ('rms_velocity_estimate_error_rad_s', 'rms_disturbance_estimate_error_rad_s2'):
        row[key] = float('nan') if row[key] is None else row[key]
    return row


def _groups(spec: SweepSpec, indices: np.ndarray) -> list[np.ndarray]:
    """Positions within ``indices`` that can share a batch.

    They share the values of every quantity that cannot vary inside a batch.
    """
    table = quantities(spec.base.controller)
    scalar_names = [n for n in spec.table if not table[n].vector]
    if not scalar_names:
        return [np.arange(len(indices))]
    keys = np.stack([spec.table[n][indices] for n in scalar_names], axis=1)
    _, inverse = np.unique(keys, axis=0, return_inverse=True)
    return [np.flatnonzero(inverse.ravel() == g) for g in range(inverse.max() + 1)]


def run_chunk(spec: SweepSpec, chunk: int) -> dict[str, list]:
    """Columns (name -> list, one entry per run) of chunk ``chunk`` of the study.

    The chunk's runs go through ClosedLoop batches of at most ``spec.batch`` runs, one group
    of equal non-vector quantities at a time (another batching may move the last bits: numpy's
    SIMD loops can round an element by its position).
    """
    indices = spec.chunk_indices(chunk)
    seeds = run_seeds(spec.seed, indices)
    table = quantities(spec.base.controller)
    metrics = {key: [None] * len(indices) for key in METRIC_COLUMNS}
    for group in _groups(spec, indices):
        for start in range(0, len(group), spec.batch):
            part = group[start : start + spec.batch]
            values: dict[str, Any] = {}  # a float, or a vector's array
            for name, column in spec.table.items():
                v = column[indices[part]]
                values[name] = float(v[0]) if not table[name].vector else v
            cols = run_batch(spec.base, values, seeds[part])
            for key in METRIC_COLUMNS:
                for pos, x in zip(part, cols[key].tolist()):
                    metrics[key][pos] = x
    columns: dict[str, list] = {
        'run': [int(i) for i in indices],
        'chunk': [chunk] * len(indices),
        'seed': [int(s) for s in seeds],
    }
    for name, column in spec.table.items():
        columns[name] = [float(v) for v in column[indices]]
    columns.update(metrics)
    return columns
