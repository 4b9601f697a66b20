# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A sweep from request to folder: build the study, run the missing chunks, join, summarise, draw.

Chunks run locally or on Ray (``distributed``), each written as soon as it finishes, with a
tqdm progress bar over runs. Nothing that exists is overwritten: a new study needs a new
folder; ``resume`` continues one that asks exactly the same.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from actuator_core.metrics import STEADY_STATE_START_S
from actuator_studies import distributed, plots, results
from actuator_studies.gains_yaml import read_gains_yaml
from actuator_studies.provenance import provenance
from actuator_studies.runner import SweepSpec
from actuator_studies.space import (
    BaseScenario,
    StudyInputError,
    check_batchable,
    parse_axis,
    parse_setting,
    sample,
)

#: Runs per vectorised ClosedLoop by default (the per-sample cost is shared by the batch).
DEFAULT_BATCH = 8192


@dataclass
class SweepRequest:
    """Everything a user asks of a sweep (what study.json records, minus where it runs)."""

    vary: list = field(default_factory=list)
    set: list = field(default_factory=list)
    method: str = 'grid'
    samples: int = 0
    seed: int = 0
    batch: int = DEFAULT_BATCH
    chunk: int = 0  # runs per chunk (task, file); 0: one batch
    repeat: int = 1  # runs per design point, each with its own seed
    controller: str = 'pp_nftsmc_eso'
    reference: str = 'fast'
    condition: str = 'deep_sea'
    duration_s: float = 10.0
    gains: str = ''

    def as_dict(self) -> dict:
        """JSON-ready form, with the gains file's text (a changed file is a different study)."""
        d = dict(self.__dict__)
        d['gains_text'] = Path(self.gains).read_text() if self.gains else ''
        return d


def build_spec(req: SweepRequest) -> tuple[SweepSpec, list[str]]:
    """Return the SweepSpec of a request and the varied names; StudyInputError on any bad input."""
    if req.batch < 1 or req.chunk < 0:
        raise StudyInputError(
            f'batch size must be >= 1 and chunk size >= 0, got {req.batch} and {req.chunk}'
        )
    if not req.duration_s > STEADY_STATE_START_S:
        raise StudyInputError(
            f'duration must exceed the steady-state window start ({STEADY_STATE_START_S:g} s)'
        )
    gains, eso, controller = None, None, req.controller
    if req.gains:
        controller, gains, eso = read_gains_yaml(Path(req.gains))
    axes = [parse_axis(text, controller) for text in req.vary]
    fixed = tuple(parse_setting(text, controller) for text in req.set)
    if req.method != 'grid' and req.samples < 1:
        raise StudyInputError(
            f'sample count must be >= 1 for --method {req.method}, got {req.samples}'
        )
    if req.repeat < 1:
        raise StudyInputError(f'repeat count must be >= 1, got {req.repeat}')
    table = {
        k: np.repeat(v, req.repeat)
        for k, v in sample(axes, req.method, req.samples, req.seed).items()
    }
    base = BaseScenario(
        controller=controller,
        reference=req.reference,
        condition=req.condition,
        duration_s=req.duration_s,
        gains=gains,
        fixed=fixed,
        **({'eso': eso} if eso is not None else {}),
    )
    names = [a.name for a in axes]
    base.values_with({n: 0.0 for n in names})  # refuses a name both varied and set
    check_batchable(base, axes)
    spec = SweepSpec(base=base, table=table, batch=req.batch, seed=req.seed, chunk_runs=req.chunk)
    return spec, names


def execute(
    spec: SweepSpec,
    out: Path,
    pending: list[int],
    ray_target: str = '',
    inject=None,
    progress: bool = True,
    ray_session=None,
) -> dict:
    """Run the pending chunks (locally or on Ray), writing each as it finishes.

    Return run statistics. ``ray_session``: an already started ray module to use (and leave
    running), e.g. a test fixture's.
    """
    start = time.perf_counter()
    ray = ray_session or (distributed.start_ray(ray_target) if ray_target else None)
    workers = distributed.ray_workers(ray) if ray else 1
    ray_start_s = time.perf_counter() - start
    runs = sum(len(spec.chunk_indices(c)) for c in pending)
    bar = tqdm(total=runs, unit='run', disable=not progress, desc='sweep', dynamic_ncols=True)
    run_start = time.perf_counter()
    try:
        stream = (
            distributed.run_ray(ray, spec, pending, inject)
            if ray
            else distributed.run_local(spec, pending, inject)
        )
        for chunk, columns in stream:
            results.write_chunk(out, chunk, columns)
            bar.update(len(columns['run']))
    finally:
        bar.close()
        wall = time.perf_counter() - run_start
        if ray is not None and ray_session is None:
            ray.shutdown()
    return {
        'executor': f'ray {ray_target or "session"}' if ray else 'local',
        'workers': workers,
        'ray_start_s': ray_start_s if ray_session is None else 0.0,
        'runs_this_call': runs,
        'wall_s': wall,
        'runs_per_s': runs / wall if wall > 0 else float('nan'),
        'load_average': list(os.getloadavg()),
    }


def run_sweep(
    req: SweepRequest,
    out: Path,
    resume: bool = False,
    ray_target: str = '',
    plot: tuple = (),
    inject=None,
    progress: bool = True,
    ray_session=None,
) -> dict:
    """Run the whole command.

    check, (re)start the folder, run what is missing, join, summarise, draw.
    """
    spec, names = build_spec(req)
    if ray_target:
        target, _ = distributed.parse_ray_target(ray_target)
    if out.exists() and not resume:
        raise StudyInputError(
            f'output folder {out} exists (use --resume to continue it, or another --out)'
        )
    for axis in plot:
        if axis not in names:
            raise StudyInputError(f'--plot {axis!r} is not a varied quantity ({", ".join(names)})')
    if ray_target and target != 'local':
        distributed.check_reachable(target)
    results.prepare_folder(
        out,
        {
            **req.as_dict(),
            'provenance': provenance(
                {'study': req.seed, 'per_run': 'SeedSequence([study, run]), 63 bits'}
            ),
        },
        resume,
    )
    done = results.finished_chunks(out, spec.chunks)
    pending = [c for c in range(spec.chunks) if c not in done]
    stats = (
        execute(spec, out, pending, ray_target, inject, progress, ray_session)
        if pending
        else {'executor': 'none (all chunks were finished)', 'runs_this_call': 0}
    )
    table = results.join_chunks(out, spec.chunks)
    earlier = results.read_summary(out).get('executions', [])  # a resumed study keeps its history
    summary = results.summarise(
        table,
        names,
        {
            'method': req.method,
            'varied': names,
            'fixed': dict(spec.base.fixed),
            'seed': req.seed,
            'batch': req.batch,
            'chunk_runs': spec.chunk_size,
            'chunks': spec.chunks,
            'chunks_resumed': len(done),
            'controller': spec.base.controller,
            'reference': req.reference,
            'condition': req.condition,
            'duration_s': req.duration_s,
            'gains_file': req.gains,
            'execution': stats,
            'executions': earlier + [stats],
        },
    )
    figures = []
    x_y = list(plot) if len(plot) == 2 else names[:2]
    if len(x_y) == 2:
        figures.append(
            str(
                plots.draw_maps(
                    table,
                    x_y[0],
                    x_y[1],
                    out / 'figures' / 'map.png',
                    req.method == 'grid',
                    title=_title(req),
                )
            )
        )
    if req.method != 'grid' or len(names) == 1:
        figures.append(str(plots.draw_cdfs(table, out / 'figures' / 'cdf.png', title=_title(req))))
    summary['figures'] = figures
    results.write_summary(out, summary)
    return summary


def _title(req: SweepRequest) -> str:
    """Figure title: controller, reference, condition and method."""
    draws = f' ({req.samples} draws, seed {req.seed})' if req.method != 'grid' else ''
    return (
        f'{req.controller}, {req.reference} trajectory, base {req.condition}, '
        f'{req.duration_s:g} s; {req.method}{draws}'
    )


def table_arrays(out: Path) -> dict[str, np.ndarray]:
    """runs.parquet of a study as arrays (for tests and reports)."""
    import pyarrow.parquet as pq

    table = pq.read_table(out / 'runs.parquet')
    return {n: np.asarray(table.column(n).to_pylist()) for n in table.column_names}
