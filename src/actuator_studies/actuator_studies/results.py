# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A study's folder.

Its definition, one Parquet file per finished chunk, the joined table and summary. Layout of
``out/``: ``study.json`` (the request, to check a resumed run asks the same, and its provenance),
``chunks/chunk_NNNNN.parquet`` (written to a temporary name and renamed, so a chunk file is either
complete or absent), ``runs.parquet`` (every row, by run index), ``summary.json`` and ``figures/``.
A rerun with ``--resume`` keeps the finished chunks and runs only the others.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from actuator_core.limits import SATURATED_FRACTION_LIMIT
from actuator_studies.space import StudyInputError

#: Max ss error [rad] above which a run counts as failed (a diverged run always does).
FAILED_ERROR_RAD = 1.0e-2


def chunk_path(out: Path, chunk: int) -> Path:
    """File of chunk ``chunk``."""
    return out / 'chunks' / f'chunk_{chunk:05d}.parquet'


def prepare_folder(out: Path, request: dict, resume: bool) -> None:
    """Create ``out`` for a new study.

    Or check that a resumed one asks exactly what it asked before.
    """
    definition = out / 'study.json'
    if out.exists() and not resume:
        raise StudyInputError(
            f'output folder {out} exists (use --resume to continue it, or another --out)'
        )
    if resume and definition.exists():
        before = json.loads(definition.read_text())
        before.pop('provenance', None)  # who ran it may differ; what it asks may not
        asked = {k: v for k, v in request.items() if k != 'provenance'}
        if before != json.loads(json.dumps(asked)):
            raise StudyInputError(
                f'--resume: {out} holds a different study ({definition} differs from this request)'
            )
    (out / 'chunks').mkdir(parents=True, exist_ok=True)
    if not definition.exists():
        definition.write_text(json.dumps(request, indent=2))


def finished_chunks(out: Path, chunks: int) -> set[int]:
    """Chunks whose file exists."""
    return {c for c in range(chunks) if chunk_path(out, c).exists()}


def write_chunk(out: Path, chunk: int, columns: dict[str, list]) -> None:
    """Write one chunk's rows atomically (temporary file, then rename)."""
    path = chunk_path(out, chunk)
    tmp = path.with_suffix('.tmp')
    arrays = {
        k: pa.array(v, type=pa.uint64()) if k == 'seed' else pa.array(v)
        for k, v in columns.items()
    }
    pq.write_table(pa.table(arrays), tmp)
    os.replace(tmp, path)


def join_chunks(out: Path, chunks: int) -> pa.Table:
    """Every chunk's rows in run order, written to runs.parquet; refuses a missing chunk."""
    missing = sorted(set(range(chunks)) - finished_chunks(out, chunks))
    if missing:
        raise RuntimeError(f'{len(missing)} chunk(s) missing: {missing[:10]}')
    table = pa.concat_tables([pq.read_table(chunk_path(out, c)) for c in range(chunks)])
    table = table.sort_by('run')
    pq.write_table(table, out / 'runs.parquet')
    return table


def _stats(x: np.ndarray) -> dict:
    """min, median, 95th percentile and max of the finite values (None when there are none)."""
    x = x[np.isfinite(x)]
    if not x.size:
        return {'count': 0}
    return {
        'count': int(x.size),
        'min': float(x.min()),
        'median': float(np.median(x)),
        'p95': float(np.percentile(x, 95)),
        'max': float(x.max()),
    }


def summarise(table: pa.Table, varied: list[str], extra: dict) -> dict:
    """Summarise.

    Counts of diverged, saturated and out-of-envelope runs, error statistics, worst run.
    """
    col = {
        name: np.asarray(table.column(name).to_pylist(), dtype=float)
        for name in table.column_names
        if name not in ('bounds_kept', 'diverged')
    }
    diverged = np.asarray(table.column('diverged').to_pylist(), dtype=bool)
    err = col['max_steady_error_rad']
    worst = None
    if np.isfinite(err).any():
        i = int(np.nanargmax(err))
        worst = {
            'run': int(col['run'][i]),
            **{n: float(col[n][i]) for n in varied},
            'max_steady_error_rad': float(err[i]),
        }
    summary = {
        'runs': int(table.num_rows),
        'diverged': int(diverged.sum()),
        'saturated_runs': int((col['saturated_fraction'] > SATURATED_FRACTION_LIMIT).sum()),
        'saturated_fraction_limit': SATURATED_FRACTION_LIMIT,
        'envelope_violated_runs': int((col['paper_envelope_violations'] > 0).sum()),
        'failed_runs': int((diverged | ~(err <= FAILED_ERROR_RAD)).sum()),
        'failed_error_rad': FAILED_ERROR_RAD,
        'max_steady_error_rad': _stats(err),
        'rms_error_rad': _stats(col['rms_error_rad']),
        'saturated_fraction': _stats(col['saturated_fraction']),
        'max_abs_current_a': _stats(col['max_abs_current_a']),
        'worst_run': worst,
        'ranges': {n: [float(np.min(col[n])), float(np.max(col[n]))] for n in varied},
        **extra,
    }
    return summary


def read_summary(out: Path) -> dict:
    """summary.json of an earlier call on ``out`` ({} when there is none)."""
    path = out / 'summary.json'
    return json.loads(path.read_text()) if path.exists() else {}


def write_summary(out: Path, summary: dict) -> Path:
    """summary.json in ``out``."""
    path = out / 'summary.json'
    path.write_text(json.dumps(summary, indent=2))
    return path


def tables_identical(a: pa.Table, b: pa.Table) -> bool:
    """Check for the same schema and the same value in every cell, NaN equal to NaN.

    pyarrow's equals says NaN != NaN.
    """
    if a.schema != b.schema or a.num_rows != b.num_rows:
        return False
    for name in a.column_names:
        x, y = (
            a.column(name).to_numpy(zero_copy_only=False),
            b.column(name).to_numpy(zero_copy_only=False),
        )
        same = (
            np.array_equal(x, y, equal_nan=True) if x.dtype.kind == 'f' else np.array_equal(x, y)
        )
        if not same:
            return False
    return True


def group_table(out: Path, by: str) -> list[dict]:
    """Per value of ``by`` (comma-separated names): runs, failed, diverged, errors, saturation.

    The figures the tables of docs/studies.md#what-the-studies-found quote, from runs.parquet.
    """
    table = pq.read_table(out / 'runs.parquet')
    names = [n for n in by.split(',') if n]
    missing = [n for n in names if n not in table.column_names]
    if missing or not names:
        raise StudyInputError(f'{",".join(missing) or by!r} is not a column of {out}/runs.parquet')
    col = {n: np.asarray(table.column(n).to_pylist(), dtype=float) for n in
           (*names, 'max_steady_error_rad', 'saturated_fraction', 'diverged',
            'paper_envelope_violation_fraction')}  # fmt: skip
    keys = np.stack([col[n] for n in names], axis=1)
    rows = []
    for value in np.unique(keys, axis=0):
        m = np.all(keys == value, axis=1)
        err = col['max_steady_error_rad'][m]
        finite = err[np.isfinite(err)]
        rows.append(
            {
                **{n: float(v) for n, v in zip(names, value)},
                'failed': int(
                    np.sum(col['diverged'][m].astype(bool) | ~(err <= FAILED_ERROR_RAD))
                ),
                'runs': int(m.sum()),
                'diverged': int(col['diverged'][m].sum()),
                'min_max_ss_error_rad': float(finite.min()) if finite.size else None,
                'max_max_ss_error_rad': float(finite.max()) if finite.size else None,
                'max_saturated_fraction': float(col['saturated_fraction'][m].max()),
                'max_envelope_violation_fraction': float(
                    col['paper_envelope_violation_fraction'][m].max()
                ),
            }
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    """``python -m actuator_studies.results STUDY --by NAME``: the per-value table of a study."""
    import argparse

    from tabulate import tabulate

    p = argparse.ArgumentParser(prog='python -m actuator_studies.results')
    p.add_argument('study', type=Path)
    p.add_argument('--by', required=True, help='the column to group by')
    a = p.parse_args(argv)
    try:
        rows = group_table(a.study, a.by)
    except (StudyInputError, OSError) as exc:
        print(f'results: error: {exc}', file=__import__('sys').stderr)
        return 2
    print(tabulate(rows, headers='keys', tablefmt='github', floatfmt='.3g'))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
