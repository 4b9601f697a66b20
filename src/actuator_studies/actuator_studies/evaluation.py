# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Gain sets judged over a set of cases: their margins and their closed-loop runs.

A case is one point of the envelope with one noise seed. ``Evaluator`` holds the cases, the
distinct plants among them (computed once) and their drift vertices (eq. (41)), and runs gain
sets over every case as one vectorised batch, in this process or as Ray tasks (one slice per
worker, through ``distributed.stream_tasks``: errors in full, lost workers retried). Case seeds
are SeedSequence([seed, tag, i]) (63 bits): the search, the held-out seeds and the held-out
interior points use different tags, so they never share a noise sequence.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from actuator_controller.laws import PpNftsmcGains
from actuator_core import limits
from actuator_eso.observer import EsoGains
from actuator_plant.model import PlantParameters
from actuator_sim.stability import drift_extremes, loop_jacobian, spectral_radius
from actuator_studies import distributed
from actuator_studies.runner import run_batch
from actuator_studies.space import BaseScenario, build_scenario

#: Error [rad] a diverged case counts as (the divergence limit itself).
DIVERGED_ERROR_RAD = limits.DIVERGENCE_ERROR_RAD
#: Command delays [samples] the margin must hold for, the likeliest to fail first.
DELAYS = (2, 1, 0)
#: Frozen times [s] along the PPF envelope where the radius is evaluated.
ENVELOPE_TIMES_S = (0.0, 2.0, 5.0, 10.0)
#: Seed tags: the search's cases, held-out seeds, held-out interior points.
SEARCH_TAG, HELD_OUT_SEEDS_TAG, INTERIOR_TAG = 0, 1, 2


def case_seeds(seed: int, tag: int, count: int) -> np.ndarray:
    """63-bit noise seeds of ``count`` cases: SeedSequence([seed, tag, i])."""
    return np.array(
        [
            np.random.SeedSequence([seed, tag, i]).generate_state(1, dtype=np.uint64)[0] >> 1
            for i in range(count)
        ],
        dtype=np.uint64,
    )


def split_gains(
    values: dict[str, float], eso: EsoGains | None = None
) -> tuple[PpNftsmcGains, EsoGains]:
    """PP gains and ESO gains from a trial's named values.

    The others keep Table 4's; the observer's nominal model is ``eso``'s (default Table 1's).
    """
    g: dict[str, Any] = {
        k.split('.', 1)[1]: v for k, v in values.items() if k.startswith('pp_nftsmc_eso.')
    }
    return dataclasses.replace(PpNftsmcGains(), **g), dataclasses.replace(
        eso or EsoGains(), omega0_rad_s=values['eso.omega0_rad_s']
    )


def worst_radius(
    values: dict[str, float],
    plants: list[PlantParameters],
    stop_above: float = np.inf,
    eso: EsoGains | None = None,
) -> dict[int, float]:
    """Worst spectral radius over ``plants`` and ENVELOPE_TIMES_S, per command delay.

    Stops at the first radius above ``stop_above`` (that delay then holds it, a lower bound of
    its worst; the delays not reached are absent): enough to call a trial infeasible.
    """
    gains, eso = split_gains(values, eso)
    out: dict[int, float] = {}
    for d in DELAYS:
        worst = 0.0
        for plant in plants:
            for t in ENVELOPE_TIMES_S:
                r = spectral_radius(
                    loop_jacobian(
                        'pp_nftsmc_eso', gains, eso=eso, t_s=t, plant=plant, plant_delay=d
                    )
                )
                worst = max(worst, r)
                if worst > stop_above:
                    out[d] = worst
                    return out
        out[d] = worst
    return out


def evaluate_slice(base: BaseScenario, values: dict[str, np.ndarray], seeds: np.ndarray):
    """Return (max ss error, saturated fraction) of one vectorised batch.

    A diverged run counts as DIVERGED_ERROR_RAD.
    """
    cols = run_batch(base, values, seeds)
    err = np.where(cols['diverged'], DIVERGED_ERROR_RAD, cols['max_steady_error_rad'])
    return np.where(np.isfinite(err), err, DIVERGED_ERROR_RAD), cols['saturated_fraction']


def _noisy(base: BaseScenario, cases: dict[str, np.ndarray], n: int) -> np.ndarray:
    """Per case: whether its encoder adds noise (so that its seed matters)."""
    noise = cases.get('encoder.noise_std_rad')
    if noise is None:
        noise = np.full(n, dict(base.fixed).get('encoder.noise_std_rad', 0.0))
    return np.asarray(noise, dtype=float) > 0.0


class Evaluator:
    """Runs gain sets over the cases as one batch, in this process or as Ray tasks."""

    def __init__(
        self,
        base: BaseScenario,
        corners: dict[str, np.ndarray],
        ray=None,
        workers: int = 1,
        seed: int = 0,
        noise_seeds: int = 1,
        tag: int = SEARCH_TAG,
    ):
        """Expand the corners into cases (noise_seeds per noisy corner); find distinct plants."""
        self.base, self.ray, self.workers = base, ray, max(1, workers)
        n = len(next(iter(corners.values())))
        reps = np.where(_noisy(base, corners, n), noise_seeds, 1)
        self.corner_of_case = np.repeat(np.arange(n), reps)
        self.cases = {
            k: np.asarray(v, dtype=float)[self.corner_of_case] for k, v in corners.items()
        }
        self.n_cases = len(self.corner_of_case)
        self.seeds = case_seeds(seed, tag, self.n_cases)
        plants: list[PlantParameters] = []
        for i in range(n):
            plant = build_scenario(base, {k: float(v[i]) for k, v in corners.items()}).plant
            if plant not in plants:
                plants.append(plant)
        self.plants = plants
        self.margin_plants: list[PlantParameters] = []
        for plant in plants:
            for vertex in drift_extremes(plant, viscous=False):
                if vertex not in self.margin_plants:
                    self.margin_plants.append(vertex)
        if ray is not None:
            self._run_remote = ray.remote(evaluate_slice)
            self._radius_remote = ray.remote(worst_radius)

    def radii(self, value_sets: list[dict], stop_above: float = np.inf) -> list[dict[int, float]]:
        """worst_radius of each gain set over the margin plants (Ray: one task per set)."""
        if self.ray is None:
            return [
                worst_radius(v, self.margin_plants, stop_above, self.base.eso) for v in value_sets
            ]
        plants_ref = self.ray.put(self.margin_plants)
        calls = [(v, plants_ref, stop_above, self.base.eso) for v in value_sets]
        return self._in_order(self._radius_remote, calls, 'the margin of a trial')

    def _in_order(self, remote, calls: list[tuple], what: str) -> list:
        """Results of Ray tasks ``remote(*call)`` in the order of ``calls``."""
        position = {id(c): i for i, c in enumerate(calls)}
        results = [None] * len(calls)
        for args, result in distributed.stream_tasks(
            self.ray, remote, calls, label=lambda args: what
        ):
            results[position[id(args)]] = result
        return results

    def run(
        self, gain_sets: list[dict[str, float]], cases: np.ndarray | None = None
    ) -> list[dict[str, np.ndarray]]:
        """Per gain set: arrays of max ss error and saturated fraction over the cases.

        All cases, or the indices ``cases``. Every gain set sees the same cases with the same
        seeds; the runs are split into one slice per worker.
        """
        if not gain_sets:
            return []
        pick = np.arange(self.n_cases) if cases is None else np.asarray(cases, dtype=int)
        nc = len(pick)
        table = {name: np.repeat([g[name] for g in gain_sets], nc) for name in gain_sets[0]}
        table.update({k: np.tile(v[pick], len(gain_sets)) for k, v in self.cases.items()})
        seeds = np.tile(self.seeds[pick], len(gain_sets))
        n = len(seeds)
        size = -(-n // self.workers)
        slices = [slice(i, min(i + size, n)) for i in range(0, n, size)]
        parts = [({k: v[s] for k, v in table.items()}, seeds[s]) for s in slices]
        if self.ray is None:
            outcome = [evaluate_slice(self.base, values, part) for values, part in parts]
        else:
            base_ref = self.ray.put(self.base)
            calls = [(base_ref, values, part) for values, part in parts]
            outcome = self._in_order(self._run_remote, calls, 'an evaluation slice')
        err = np.concatenate([o[0] for o in outcome])
        sat = np.concatenate([o[1] for o in outcome])
        return [
            {
                'error_rad': err[i * nc : (i + 1) * nc],
                'saturated_fraction': sat[i * nc : (i + 1) * nc],
            }
            for i in range(len(gain_sets))
        ]
