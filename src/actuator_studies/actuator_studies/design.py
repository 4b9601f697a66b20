# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Robust PP-NFTSMC-ESO gain design: Optuna TPE over (k0, k1, k2, k3, omega0) for the envelope.

Objective: the chosen percentile (default 100, the worst case) of the max steady-state
error over the design cases: every corner of the envelope (the product of the --corner
values), a corner with encoder noise once per noise seed (``--noise-seeds``, derived from
--seed); a diverged case counts as DIVERGED_ERROR_RAD. Constraints (Optuna's constrained TPE, a
trial is feasible when every value is <= 0):
  1. margin: the spectral radius of the linearised sampled loop (``actuator_sim.stability``)
     at 0, 1 and 2 samples of command delay, at frozen times along the PPF envelope, for every
     distinct corner plant (stirring loss of its depth and temperature) at the vertices of the
     drift of eq. (41) (J and k_t at both extremes, k_b at its low one: the k_b vertices moved
     the radius by less than 2e-4 in a check of the committed gains), at most the target radius;
  2. current: at most SATURATED_FRACTION_LIMIT of the samples at the current limit, every case.
Trials are asked ``parallel`` at a time (constant liar); their margins, then the cases of the
stable ones as one vectorised batch, run locally or as Ray tasks. A trial that fails the margin
is not simulated; with ``prune`` (worst case only) a stable trial that is already worse than
the best feasible one on the hard quarter of the cases is not run on the rest (``_simulate``).
The paper's Table 4 gains are the first trial of a new study. With
``--storage FILE`` the Optuna study lives in a journal file: a design that stops resumes
there, and several drivers may share it.

With ``--joint FILE`` (``bag_identify --params``) the design is for an identified joint: its
theta1, theta2 are the observer's and the law's nominal model and the plant is that joint
(``identified_plant``), with the drift of eq. (41) around it in the margin and, by default, no
and two samples of command delay as the corners.

The result is validated out of sample (``validate``): on the design corners with noise seeds
the search never saw, and on Latin-hypercube points inside the corners' box with their own
seeds. design.json labels the search's own figures ``in_sample``.

python-control is not used: the margin is the eigenvalues of the Jacobian that
``actuator_sim.stability`` builds. Ray Tune is not used either: ``ray.tune`` is not installed
here (its extra dependencies are not in the locks), so Optuna drives the search and Ray runs
the batches.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from actuator_controller.laws import PpNftsmcGains
from actuator_core import limits
from actuator_eso.observer import EsoGains
from actuator_studies import distributed
from actuator_studies.evaluation import (
    DELAYS,
    DIVERGED_ERROR_RAD,
    ENVELOPE_TIMES_S,
    HELD_OUT_SEEDS_TAG,
    INTERIOR_TAG,
    SEARCH_TAG,
    Evaluator,
    split_gains,
)
from actuator_studies.gains_yaml import write_gains_yaml
from actuator_studies.identified_plant import JOINT_CORNERS, joint_design, read_joint
from actuator_studies.provenance import provenance
from actuator_studies.results import FAILED_ERROR_RAD
from actuator_studies.space import (
    BaseScenario,
    StudyInputError,
    lookup,
    parse_axis,
    parse_setting,
)

__all__ = ['DELAYS', 'ENVELOPE_TIMES_S', 'Evaluator', 'split_gains']

#: Searched gains: (quantity name, low, high), sampled log-uniformly.
SEARCH_SPACE = (
    ('pp_nftsmc_eso.k0_per_s', 20.0, 400.0),
    ('pp_nftsmc_eso.k1', 100.0, 10000.0),
    ('pp_nftsmc_eso.k2', 2.0, 200.0),
    ('pp_nftsmc_eso.k3_per_s', 20.0, 2000.0),
    ('eso.omega0_rad_s', 20.0, 150.0),
)
#: Default corners: the depth range the joint can drive at all
#: (docs/studies.md#depth-and-temperature-where-it-breaks: beyond about 2500 m the seal friction of
#: eq. (42) takes the motor's torque at the current limit), both ends of the temperature range, and
#: no and two samples of command delay.
DEFAULT_CORNERS = (
    'depth_m=0,1000,2000',
    'condition.temperature_c=-2,30',
    'command_delay_samples=0,2',
)


@dataclass
class DesignRequest:
    """What ``design_gains`` is asked."""

    trials: int = 48
    parallel: int = 8
    seed: int = 0
    percentile: float = 100.0
    target_radius: float | None = None
    corners: list = field(default_factory=list)
    settings: list = field(default_factory=list)
    controller: str = 'pp_nftsmc_eso'
    reference: str = 'fast'
    condition: str = 'deep_sea'
    duration_s: float = 10.0
    noise_seeds: int = 3  # per corner with encoder noise, in the search
    validate_seeds: int = 5  # held-out seeds per noisy corner
    validate_points: int = 40  # held-out Latin-hypercube points inside the corners' box
    storage: str = ''  # Optuna journal file ('' : in memory)
    prune: bool = False  # exact pruning over the cases (worst case only)
    study_name: str = 'design_gains'
    joint: str = ''  # an identified joint's parameter file (bag_identify --params): its model


def corner_table(corners: list[str], controller: str) -> dict[str, np.ndarray]:
    """Return the product of every corner axis's values, one array per quantity."""
    axes = [parse_axis(text, controller) for text in (corners or DEFAULT_CORNERS)]
    columns = list(zip(*itertools.product(*(a.grid_values() for a in axes))))
    return {a.name: np.asarray(c, dtype=float) for a, c in zip(axes, columns)}


def interior_table(
    corners: dict[str, np.ndarray], points: int, seed: int, controller: str
) -> dict[str, np.ndarray]:
    """Latin-hypercube points in the box of the corners (whole-number quantities rounded)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, INTERIOR_TAG]))
    table = {}
    for name, values in corners.items():
        low, high = float(np.min(values)), float(np.max(values))
        u = (rng.permutation(points) + rng.uniform(size=points)) / points
        x = low + u * (high - low)
        table[name] = np.round(x) if lookup(name, controller).integer else x
    return table


def paper_values() -> dict[str, float]:
    """Table 4's values of the searched gains."""
    return gain_values(PpNftsmcGains(), EsoGains())


def gain_values(g: PpNftsmcGains, eso: EsoGains) -> dict[str, float]:
    """Return the searched gains of a gain set by name (the inverse of split_gains)."""
    return {
        'pp_nftsmc_eso.k0_per_s': g.k0_per_s,
        'pp_nftsmc_eso.k1': g.k1,
        'pp_nftsmc_eso.k2': g.k2,
        'pp_nftsmc_eso.k3_per_s': g.k3_per_s,
        'eso.omega0_rad_s': eso.omega0_rad_s,
    }


def _objective(errors: np.ndarray, percentile: float) -> float:
    """Return the percentile of the cases' max steady-state errors [rad]."""
    return float(np.percentile(errors, percentile))


def open_study(req: DesignRequest):
    """Open the Optuna study: new in memory, or created or resumed in the journal --storage."""
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    sampler = optuna.samplers.TPESampler(
        seed=req.seed, constant_liar=True, n_startup_trials=min(16, req.trials)
    )
    storage = None
    if req.storage:
        from optuna.storages import JournalStorage
        from optuna.storages.journal import JournalFileBackend

        storage = JournalStorage(JournalFileBackend(req.storage))
    study = optuna.create_study(
        direction='minimize',
        sampler=sampler,
        storage=storage,
        study_name=req.study_name if storage is not None else None,
        load_if_exists=storage is not None,
    )
    if storage is not None:
        attrs = study.user_attrs
        asked = {'corners': req.corners, 'settings': req.settings, 'seed': req.seed,
                 'noise_seeds': req.noise_seeds, 'duration_s': req.duration_s,
                 'percentile': req.percentile, 'target_radius': req.target_radius}  # fmt: skip
        if req.joint:  # asked only then: the journals of earlier designs resume as they were
            asked['joint'] = req.joint
        if not attrs:
            for k, v in asked.items():
                study.set_user_attr(k, v)
        elif {k: attrs.get(k) for k in asked} != json.loads(json.dumps(asked)):
            raise StudyInputError(
                f'--storage {req.storage}: study {req.study_name!r} was asked something else '
                '(corners, settings, seeds, duration, percentile or target differ)'
            )
    if not study.trials:
        study.enqueue_trial(paper_values())
    return study


def _completed_records(study) -> list[dict]:
    """Return the records of the study's completed trials, in trial order."""
    import optuna

    return [
        t.user_attrs['record']
        for t in sorted(study.trials, key=lambda t: t.number)
        if t.state == optuna.trial.TrialState.COMPLETE and 'record' in t.user_attrs
    ]


def _simulate(
    evaluator: Evaluator, values: list[dict], stable: list[int], incumbent, req: DesignRequest
) -> tuple[dict, set]:
    """Errors and saturation of the stable trials; pruned ones scored on the hard cases only.

    Exact pruning for the worst case (percentile 100, ``--prune``): the trials are first run
    on the quarter of the cases where the incumbent (best feasible so far) did worst; a trial
    whose worst there already exceeds the incumbent's objective cannot become the best, and its
    other cases are not run (its objective is recorded as that lower bound, flagged pruned).
    """
    chosen = [values[i] for i in stable]
    if not (req.prune and req.percentile == 100.0 and incumbent and chosen):
        return dict(zip(stable, evaluator.run(chosen))), set()
    errors = np.asarray(incumbent['case_errors_rad'])
    order = np.argsort(-errors, kind='stable')
    hard, rest = order[: max(1, len(order) // 4)], order[max(1, len(order) // 4) :]
    first = evaluator.run(chosen, hard)
    pruned = {
        i for i, o in zip(stable, first) if np.max(o['error_rad']) > incumbent['objective_rad']
    }
    survivors = [i for i in stable if i not in pruned]
    second = dict(zip(survivors, evaluator.run([values[i] for i in survivors], rest)))
    outcome = {}
    for i, o in zip(stable, first):
        if i in pruned:
            outcome[i] = o
            continue
        err, sat = np.empty(len(order)), np.empty(len(order))
        err[hard], sat[hard] = o['error_rad'], o['saturated_fraction']
        err[rest], sat[rest] = second[i]['error_rad'], second[i]['saturated_fraction']
        outcome[i] = {'error_rad': err, 'saturated_fraction': sat}
    return outcome, pruned


def search(
    evaluator: Evaluator, req: DesignRequest, target: float, log=print
) -> tuple[dict | None, list[dict]]:
    """Optuna TPE with constraints until the study holds req.trials completed trials.

    Returns (best feasible values or None, every completed trial's record).
    """
    study = open_study(req)
    records = _completed_records(study)
    if records:
        log(f'design_gains: resuming {req.study_name!r} with {len(records)} trials')
    while len(records) < req.trials:
        trials = [study.ask() for _ in range(min(req.parallel, req.trials - len(records)))]
        values = [
            {name: t.suggest_float(name, lo, hi, log=True) for name, lo, hi in SEARCH_SPACE}
            for t in trials
        ]
        radii = evaluator.radii(values, stop_above=target)
        stable = [i for i, r in enumerate(radii) if max(r.values()) <= target]
        incumbent = min(
            (r for r in records if r['feasible']), key=lambda r: r['objective_rad'], default=None
        )
        outcome, pruned = _simulate(evaluator, values, stable, incumbent, req)
        for i, (trial, v, r) in enumerate(zip(trials, values, radii)):
            margin = max(r.values()) - target
            if i in outcome:
                o = outcome[i]
                value = (
                    float(np.max(o['error_rad']))
                    if i in pruned
                    else _objective(o['error_rad'], req.percentile)
                )
                saturation = (
                    float(np.max(o['saturated_fraction'])) - limits.SATURATED_FRACTION_LIMIT
                )
            else:
                value, saturation = DIVERGED_ERROR_RAD, 1.0
            trial.set_constraint('margin', margin)  # feasible when <= 0 (Optuna 5 constrained TPE)
            trial.set_constraint('saturation', saturation)
            record = {
                'trial': trial.number,
                **v,
                'radius': {str(d): x for d, x in sorted(r.items())},
                'objective_rad': value,
                'feasible': margin <= 0 and saturation <= 0 and i not in pruned,
                'simulated': i in outcome,
                'pruned': i in pruned,  # objective_rad then a lower bound above the incumbent
            }
            if i in outcome and i not in pruned:
                record['case_errors_rad'] = [float(x) for x in outcome[i]['error_rad']]
            trial.set_user_attr('record', record)
            study.tell(trial, value)
            records.append(record)
        feasible_so_far = [r for r in records if r['feasible']]
        best_text = (
            f'best feasible {min(r["objective_rad"] for r in feasible_so_far):.3e} rad (in sample)'
            if feasible_so_far
            else 'none feasible yet'
        )
        log(f'design_gains: {len(records)}/{req.trials} trials, {best_text}')
    feasible = [r for r in records if r['feasible']]
    if not feasible:
        return None, records
    best = min(feasible, key=lambda r: r['objective_rad'])
    return {name: best[name] for name, _, _ in SEARCH_SPACE}, records


def compare(
    evaluator: Evaluator, sets: dict[str, dict], percentile: float, radii: bool = True
) -> dict:
    """Per named gain set: margin, worst/median/percentile error, saturation, failures."""
    outcomes = evaluator.run(list(sets.values()))
    table = {}
    for (label, values), o in zip(sets.items(), outcomes):
        err = o['error_rad']
        row = {
            'gains': values,
            'worst_error_rad': float(np.max(err)),
            'median_error_rad': float(np.median(err)),
            'percentile_error_rad': _objective(err, percentile),
            'failed_cases': int(np.count_nonzero(err > FAILED_ERROR_RAD)),
            'max_saturated_fraction': float(np.max(o['saturated_fraction'])),
            'cases': len(err),
        }
        if radii:
            r = evaluator.radii([values])[0]
            row['radius_by_delay'] = {str(d): x for d, x in sorted(r.items())}
        table[label] = row
    return table


def validate(
    base: BaseScenario,
    corners: dict[str, np.ndarray],
    sets: dict[str, dict],
    req: DesignRequest,
    ray=None,
    workers: int = 1,
) -> dict:
    """Held-out figures: the corners with unseen noise seeds, and interior LHS points."""
    held_seeds = Evaluator(
        base, corners, ray, workers, req.seed, req.validate_seeds, HELD_OUT_SEEDS_TAG
    )
    out = {
        'held_out_seeds': {
            'what': f'the design corners, {req.validate_seeds} unseen noise seeds per noisy one',
            **compare(held_seeds, sets, req.percentile, radii=False),
        }
    }
    if req.validate_points > 0:
        interior = interior_table(corners, req.validate_points, req.seed, req.controller)
        held_points = Evaluator(base, interior, ray, workers, req.seed, 1, INTERIOR_TAG)
        out['held_out_interior'] = {
            'what': f'{req.validate_points} Latin-hypercube points inside the corners, '
            'each with its own unseen seed',
            **compare(held_points, sets, req.percentile, radii=False),
        }
    return out


def _check(req: DesignRequest, out: Path) -> float:
    """Return the target radius; StudyInputError for bad input (before anything is written)."""
    if req.controller != 'pp_nftsmc_eso':
        raise StudyInputError(
            'design_gains designs PP-NFTSMC-ESO gains only (--controller pp_nftsmc_eso)'
        )
    if req.trials < 1 or req.parallel < 1 or req.noise_seeds < 1 or req.validate_seeds < 1:
        raise StudyInputError(
            'trials, parallel, noise seeds and validation seeds must be >= 1, got '
            f'{req.trials}, {req.parallel}, {req.noise_seeds} and {req.validate_seeds}'
        )
    if req.validate_points < 0:
        raise StudyInputError(f'validation points must be >= 0, got {req.validate_points}')
    if not 0.0 <= req.percentile <= 100.0:
        raise StudyInputError(f'percentile must be in [0, 100], got {req.percentile}')
    target = limits.DESIGN_TARGET_RADIUS if req.target_radius is None else req.target_radius
    if not 0.0 < target < 1.0:
        raise StudyInputError(f'target radius must be in (0, 1), got {target}')
    if out.exists():
        raise StudyInputError(f'output folder {out} exists (choose another --out)')
    if not req.duration_s > limits.STEADY_STATE_START_S:
        raise StudyInputError(
            f'duration must exceed the steady-state window start ({limits.STEADY_STATE_START_S} s)'
        )
    return target


def run_design(req: DesignRequest, out: Path, ray_target: str = '', log=print) -> dict:
    """Run the whole command.

    check input, search, compare in sample, validate out of sample, write gains YAML and report.
    """
    target = _check(req, out)
    fixed = tuple(parse_setting(text, req.controller) for text in req.settings)
    eso, corner_texts = EsoGains(), req.corners
    joint_notes: list[str] = []
    if req.joint:
        eso, settings, joint_notes = joint_design(read_joint(Path(req.joint)))
        joint_fixed = tuple(parse_setting(f'{n}={v!r}', req.controller) for n, v in settings)
        both = {n for n, _ in fixed} & {n for n, _ in joint_fixed}
        if both:
            raise StudyInputError(f'--joint sets {", ".join(sorted(both))}: do not --set it too')
        fixed += joint_fixed
        corner_texts = req.corners or list(JOINT_CORNERS)
    corners = corner_table(corner_texts, req.controller)
    searched = {name for name, _, _ in SEARCH_SPACE}
    clash = searched & ({n for n, _ in fixed} | set(corners))
    if clash:
        raise StudyInputError(
            f'{", ".join(sorted(clash))} is searched and cannot be set or a corner'
        )
    base = BaseScenario(
        controller=req.controller,
        reference=req.reference,
        condition=req.condition,
        duration_s=req.duration_s,
        eso=eso,
        fixed=fixed,
    )
    if ray_target:
        address, _ = distributed.parse_ray_target(ray_target)
        if address != 'local':
            distributed.check_reachable(address)
    origin = provenance({'design': req.seed, 'cases': 'SeedSequence([seed, tag, i])'})  # at start
    ray = distributed.start_ray(ray_target) if ray_target else None
    start = time.perf_counter()
    try:
        workers = distributed.ray_workers(ray) if ray else 1
        evaluator = Evaluator(base, corners, ray, workers, req.seed, req.noise_seeds, SEARCH_TAG)
        best, records = search(evaluator, req, target, log)
        sets = {'paper (Table 4)': paper_values(), **({'designed': best} if best else {})}
        comparison = compare(evaluator, sets, req.percentile)
        validation = validate(base, corners, sets, req, ray, workers)
    finally:
        if ray is not None:
            ray.shutdown()
    out.mkdir(parents=True)
    report = {
        'request': dataclasses.asdict(req),
        'provenance': origin,
        'target_radius': target,
        'delays': sorted(DELAYS),
        'envelope_times_s': list(ENVELOPE_TIMES_S),
        'corners': {k: v.tolist() for k, v in corners.items()},
        'cases': evaluator.n_cases,
        'distinct_plants': len(evaluator.plants),
        'margin_plants': len(evaluator.margin_plants),
        'search_space': [list(s) for s in SEARCH_SPACE],
        'trials': records,
        'comparison': comparison,  # in sample: the cases the search scored
        'in_sample': comparison,
        'validation': validation,
        'wall_s': time.perf_counter() - start,
        'gains_yaml': None,
        'joint': {'file': req.joint, 'notes': joint_notes} if req.joint else None,
    }
    if best:
        gains, eso = split_gains(best, base.eso)
        c = comparison['designed']
        held = validation['held_out_seeds']['designed']
        header = (
            f'PP-NFTSMC-ESO gains by design_gains '
            f'(Optuna TPE, seed {req.seed}, {req.trials} trials):\n'
            f'radius <= {target} at 0/1/2 samples of command delay over the drift vertices '
            f'({", ".join(f"{x:.4f}" for x in c["radius_by_delay"].values())}); '
            f'held-out worst max ss error {held["worst_error_rad"]:.3e} rad over '
            f'{held["cases"]} cases (in sample {c["worst_error_rad"]:.3e}).\n'
            'Load with the scenario file: --params-file <scenario>.yaml --params-file this.yaml'
        )
        if req.joint:
            header += f'\nFor the identified joint {req.joint}: load it before this file.'

        report['gains_yaml'] = str(
            write_gains_yaml(out / 'gains.yaml', 'pp_nftsmc_eso', gains, eso, header)
        )
    (out / 'design.json').write_text(
        json.dumps(report, indent=2, default=lambda x: x.item() if hasattr(x, 'item') else str(x))
    )
    return report
