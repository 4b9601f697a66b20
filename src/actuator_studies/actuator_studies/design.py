# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Robust PP-NFTSMC-ESO gain design: Optuna TPE over (k0, k1, k2, k3, omega0) for the envelope.

Objective: the chosen percentile (default 100, the worst case) of the max steady-state
error over the envelope's corners (the product of the --corner values), each corner one
closed-loop run; a diverged corner counts as DIVERGED_ERROR_RAD. Constraints (Optuna's
constrained TPE, a trial is feasible when every value is <= 0):
  1. margin: the spectral radius of the linearised sampled loop (``actuator_sim.stability``)
     at 0, 1 and 2 samples of command delay (plant applies u(k - D), the ESO integrates u(k)),
     at frozen times along the PPF envelope and with each corner's stirring loss, at most
     the target radius;
  2. current: at most SATURATED_FRACTION_LIMIT of the samples at the current limit, every corner.
Trials are asked ``parallel`` at a time (constant liar) and their corners run as one vectorised
batch (gains are per-run arrays), locally or split into one Ray task per worker (retried like a
sweep's chunks); corner i has the same encoder noise seed in every trial. A trial that fails the
margin is not simulated. The paper's Table 4 gains are the first trial.

python-control is not used: the margin is the eigenvalues of the Jacobian that
``actuator_sim.stability`` builds; ``numpy.linalg.eigvals`` on it is what python-control's
``StateSpace.poles`` would compute too, with extra construction cost (timed in the README).
Ray Tune is not used either: ``ray.tune`` is not installed here (its extra dependencies
are not in the locks), so Optuna drives the search and Ray only runs the batches.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from actuator_core import limits
from actuator_controller.laws import PpNftsmcGains
from actuator_eso.observer import EsoGains
from actuator_plant.model import PlantParameters
from actuator_sim.stability import radius_along_envelope
from actuator_studies import distributed
from actuator_studies.gains_yaml import write_gains_yaml
from actuator_studies.runner import run_batch
from actuator_studies.space import (
    BaseScenario,
    StudyInputError,
    build_scenario,
    parse_axis,
    parse_setting,
    run_seeds,
)

#: Searched gains: (quantity name, low, high), sampled log-uniformly.
SEARCH_SPACE = (
    ('pp_nftsmc_eso.k0_per_s', 20.0, 400.0),
    ('pp_nftsmc_eso.k1', 100.0, 10000.0),
    ('pp_nftsmc_eso.k2', 2.0, 200.0),
    ('pp_nftsmc_eso.k3_per_s', 20.0, 2000.0),
    ('eso.omega0_rad_s', 20.0, 150.0),
)
#: Error [rad] a diverged corner counts as (the divergence limit itself).
DIVERGED_ERROR_RAD = limits.DIVERGENCE_ERROR_RAD
#: Command delays [samples] the margin must hold for.
DELAYS = (0, 1, 2)
#: Frozen times [s] along the PPF envelope where the radius is evaluated.
ENVELOPE_TIMES_S = (0.0, 2.0, 5.0, 10.0)
#: Default corners: the depth range the joint can drive at all (README, section 1: beyond about
#: 2500 m the seal friction of eq. (42) takes the motor's torque at the current limit), both
#: ends of the temperature range, and no and two samples of command delay.
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


def corner_table(corners: list[str], controller: str) -> dict[str, np.ndarray]:
    """Return the product of every corner axis's values, one array per quantity."""
    axes = [parse_axis(text, controller) for text in (corners or DEFAULT_CORNERS)]
    columns = list(zip(*itertools.product(*(a.grid_values() for a in axes))))
    return {a.name: np.asarray(c, dtype=float) for a, c in zip(axes, columns)}


def paper_values() -> dict[str, float]:
    """Table 4's values of the searched gains."""
    g, eso = PpNftsmcGains(), EsoGains()
    return {
        'pp_nftsmc_eso.k0_per_s': g.k0_per_s,
        'pp_nftsmc_eso.k1': g.k1,
        'pp_nftsmc_eso.k2': g.k2,
        'pp_nftsmc_eso.k3_per_s': g.k3_per_s,
        'eso.omega0_rad_s': eso.omega0_rad_s,
    }


def split_gains(values: dict[str, float]) -> tuple[PpNftsmcGains, EsoGains]:
    """PP gains and ESO gains from a trial's named values (others keep Table 4's)."""
    g = {k.split('.', 1)[1]: v for k, v in values.items() if k.startswith('pp_nftsmc_eso.')}
    return dataclasses.replace(PpNftsmcGains(), **g), EsoGains(
        omega0_rad_s=values['eso.omega0_rad_s']
    )


def worst_radius(
    gains: PpNftsmcGains, eso: EsoGains, plants: list[PlantParameters]
) -> dict[int, float]:
    """Worst spectral radius along the envelope and over the corners' plants, per command delay."""
    return {
        d: max(
            r
            for plant in plants
            for _, r in radius_along_envelope(
                'pp_nftsmc_eso', gains, ENVELOPE_TIMES_S, eso=eso, plant=plant, plant_delay=d
            )
        )
        for d in DELAYS
    }


class Evaluator:
    """Runs gain sets over the corners as one batch, in this process or as Ray tasks."""

    def __init__(
        self, base: BaseScenario, corners: dict[str, np.ndarray], ray=None, workers: int = 1
    ):
        """Hold the base scenario, the corner table and, optionally, a started Ray."""
        self.base, self.corners, self.ray, self.workers = base, corners, ray, workers
        self.n_corners = len(next(iter(corners.values())))
        self.plants = [
            build_scenario(base, {k: float(v[i]) for k, v in corners.items()}).plant
            for i in range(self.n_corners)
        ]

    def run(self, gain_sets: list[dict[str, float]]) -> list[dict[str, np.ndarray]]:
        """Per gain set: arrays over the corners of max ss error and saturation.

        A diverged run counts as DIVERGED_ERROR_RAD. Corner i draws its encoder noise from seed
        run_seeds(0, [i]) for every gain set, so trials are compared on the same noise; the runs
        are split into one slice per worker.
        """
        if not gain_sets:
            return []
        table = {
            name: np.repeat([g[name] for g in gain_sets], self.n_corners) for name in gain_sets[0]
        }
        table.update({k: np.tile(v, len(gain_sets)) for k, v in self.corners.items()})
        seeds = np.tile(run_seeds(0, np.arange(self.n_corners)), len(gain_sets))
        n = len(seeds)
        size = -(-n // self.workers)
        slices = [slice(i, min(i + size, n)) for i in range(0, n, size)]
        parts = [({k: v[s] for k, v in table.items()}, seeds[s]) for s in slices]
        if self.ray is None:
            outcome = [
                evaluate_slice(self.base, values, part_seeds) for values, part_seeds in parts
            ]
        else:
            task = self.ray.remote(
                num_cpus=1, max_retries=distributed.MAX_RETRIES, retry_exceptions=True
            )(evaluate_slice)
            outcome = self.ray.get(
                [task.remote(self.base, values, part_seeds) for values, part_seeds in parts]
            )
        err = np.concatenate([o[0] for o in outcome])
        sat = np.concatenate([o[1] for o in outcome])
        return [
            {
                'error_rad': err[i * self.n_corners : (i + 1) * self.n_corners],
                'saturated_fraction': sat[i * self.n_corners : (i + 1) * self.n_corners],
            }
            for i in range(len(gain_sets))
        ]


def evaluate_slice(base: BaseScenario, values: dict[str, np.ndarray], seeds: np.ndarray):
    """Return (max ss error, saturated fraction) of one vectorised batch.

    A diverged run counts as DIVERGED_ERROR_RAD.
    """
    rows = [m for m, _ in run_batch(base, values, seeds)]
    err = np.array([DIVERGED_ERROR_RAD if m.diverged else m.max_steady_error_rad for m in rows])
    return np.where(np.isfinite(err), err, DIVERGED_ERROR_RAD), np.array(
        [m.saturated_fraction for m in rows]
    )


def _objective(errors: np.ndarray, percentile: float) -> float:
    """Return the percentile of the corners' max steady-state errors [rad]."""
    return float(np.percentile(errors, percentile))


def search(
    evaluator: Evaluator, req: DesignRequest, target: float, log=print
) -> tuple[dict, list[dict]]:
    """Optuna TPE with constraints.

    Returns (best feasible values or None, every trial's record).
    """
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    sampler = optuna.samplers.TPESampler(
        seed=req.seed, constant_liar=True, n_startup_trials=min(16, req.trials)
    )
    study = optuna.create_study(direction='minimize', sampler=sampler)
    study.enqueue_trial(paper_values())
    records = []
    while len(records) < req.trials:
        trials = [study.ask() for _ in range(min(req.parallel, req.trials - len(records)))]
        values = [
            {name: t.suggest_float(name, lo, hi, log=True) for name, lo, hi in SEARCH_SPACE}
            for t in trials
        ]
        radii = [worst_radius(*split_gains(v), evaluator.plants) for v in values]
        stable = [i for i, r in enumerate(radii) if max(r.values()) <= target]
        outcome = dict(zip(stable, evaluator.run([values[i] for i in stable])))
        for i, (trial, v, r) in enumerate(zip(trials, values, radii)):
            margin = max(r.values()) - target
            if i in outcome:
                o = outcome[i]
                value = _objective(o['error_rad'], req.percentile)
                saturation = (
                    float(np.max(o['saturated_fraction'])) - limits.SATURATED_FRACTION_LIMIT
                )
            else:
                value, saturation = DIVERGED_ERROR_RAD, 1.0
            trial.set_constraint('margin', margin)  # feasible when <= 0 (Optuna 5 constrained TPE)
            trial.set_constraint('saturation', saturation)
            study.tell(trial, value)
            records.append(
                {
                    'trial': trial.number,
                    **v,
                    'radius': {str(d): x for d, x in r.items()},
                    'objective_rad': value,
                    'feasible': margin <= 0 and saturation <= 0,
                    'simulated': i in outcome,
                }
            )
        best = [r for r in records if r['feasible']]
        best_text = (
            f'best feasible {min(r["objective_rad"] for r in best):.3e} rad'
            if best
            else 'none feasible yet'
        )
        log(f'design_gains: {len(records)}/{req.trials} trials, {best_text}')
    feasible = [r for r in records if r['feasible']]
    if not feasible:
        return None, records
    best = min(feasible, key=lambda r: r['objective_rad'])
    return {name: best[name] for name, _, _ in SEARCH_SPACE}, records


def compare(evaluator: Evaluator, sets: dict[str, dict], percentile: float) -> dict:
    """Margin, worst/median/percentile error and saturation over the corners.

    Per named gain set.
    """
    outcomes = evaluator.run(list(sets.values()))
    table = {}
    for (label, values), o in zip(sets.items(), outcomes):
        radii = worst_radius(*split_gains(values), evaluator.plants)
        table[label] = {
            'gains': values,
            'radius_by_delay': {str(d): r for d, r in radii.items()},
            'worst_error_rad': float(np.max(o['error_rad'])),
            'median_error_rad': float(np.median(o['error_rad'])),
            'percentile_error_rad': _objective(o['error_rad'], percentile),
            'max_saturated_fraction': float(np.max(o['saturated_fraction'])),
            'corners': len(o['error_rad']),
        }
    return table


def run_design(req: DesignRequest, out: Path, ray_target: str = '', log=print) -> dict:
    """Run the whole command.

    check input, search, verify on a finer envelope, write gains YAML and report.
    """
    if req.controller != 'pp_nftsmc_eso':
        raise StudyInputError(
            'design_gains designs PP-NFTSMC-ESO gains only (--controller pp_nftsmc_eso)'
        )
    if req.trials < 1 or req.parallel < 1:
        raise StudyInputError(
            f'trials and parallel must be >= 1, got {req.trials} and {req.parallel}'
        )
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
    fixed = tuple(parse_setting(text, req.controller) for text in req.settings)
    corners = corner_table(req.corners, req.controller)
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
        fixed=fixed,
    )
    if ray_target:
        address, _ = distributed.parse_ray_target(ray_target)
        if address != 'local':
            distributed.check_reachable(address)
    ray = distributed.start_ray(ray_target) if ray_target else None
    start = time.perf_counter()
    try:
        evaluator = Evaluator(base, corners, ray, distributed.ray_workers(ray) if ray else 1)
        best, records = search(evaluator, req, target, log)
        paper = paper_values()
        sets = {'paper (Table 4)': paper, **({'designed': best} if best else {})}
        comparison = compare(evaluator, sets, req.percentile)
    finally:
        if ray is not None:
            ray.shutdown()
    out.mkdir(parents=True)
    report = {
        'request': dataclasses.asdict(req),
        'target_radius': target,
        'delays': list(DELAYS),
        'envelope_times_s': list(ENVELOPE_TIMES_S),
        'corners': {k: v.tolist() for k, v in corners.items()},
        'search_space': [list(s) for s in SEARCH_SPACE],
        'trials': records,
        'comparison': comparison,
        'wall_s': time.perf_counter() - start,
        'gains_yaml': None,
    }
    if best:
        gains, eso = split_gains(best)
        c = comparison['designed']
        header = (
            f'PP-NFTSMC-ESO gains by design_gains '
            f'(Optuna TPE, seed {req.seed}, {req.trials} trials):\n'
            f'radius <= {target} at 0/1/2 samples of command delay '
            f'({", ".join(f"{x:.4f}" for x in c["radius_by_delay"].values())}); '
            f'worst max ss error {c["worst_error_rad"]:.3e} rad over {c["corners"]} corners; '
            f'max saturated fraction {c["max_saturated_fraction"]:.3f}.\n'
            'Load with the scenario file: --params-file <scenario>.yaml --params-file this.yaml'
        )
        report['gains_yaml'] = str(
            write_gains_yaml(out / 'gains.yaml', 'pp_nftsmc_eso', gains, eso, header)
        )
    (out / 'design.json').write_text(
        json.dumps(report, indent=2, default=lambda x: x.item() if hasattr(x, 'item') else str(x))
    )
    return report
