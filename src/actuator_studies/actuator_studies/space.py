# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Study space: the quantities a sweep may vary, how they are sampled, the batch scenario.

The quantities are those of the scenario. A quantity is named as the nodes name their parameters:
``depth_m``, the plant's ``condition.temperature_c``, ``drift.inertia_amplitude``,
``external.mean_nm``, ...; the observer's under ``eso.`` (``eso.omega0_rad_s``); the controller's
under its name (``pp_nftsmc_eso.k0_per_s``); ``common.current_limit_a``; the encoder's
``encoder.counts_per_rev`` and ``encoder.noise_std_rad``; and ``command_delay_samples``. Units,
ranges and descriptions come from the same ``spec`` declarations the models use.

Sampling: a grid (the Cartesian product of each quantity's points, the first quantity
varying slowest), a seeded Monte Carlo draw (independent uniforms), or a seeded Latin
hypercube (each quantity's range cut into n equal strata, one draw per stratum, strata
permuted independently per quantity). Whole-number quantities are rounded after sampling.
Run i draws its encoder noise from seed SeedSequence([seed, i]) (63 bits), so a run's noise
does not depend on the batch or the worker that runs it.
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from actuator_controller.laws import CONTROLLER_NAMES, GAINS_BY_NAME, CommonConfig
from actuator_core import limits
from actuator_core.params import iter_specs
from actuator_eso.observer import EsoGains
from actuator_plant.encoder import EncoderParameters
from actuator_plant.model import GRAVITY_M_S2, SEAWATER_DENSITY_KG_M3, PlantParameters
from actuator_sim.loop import Scenario
from actuator_sim.scenarios import CONDITIONS

METHODS = ('grid', 'mc', 'lhs')


class StudyInputError(ValueError):
    """A study request that cannot be run; its message is one line for the user."""


@dataclass(frozen=True)
class Quantity:
    """One sweepable scenario quantity: where it goes, its unit and valid range."""

    name: str
    root: str  # plant | depth | eso | gains | common | encoder | delay
    path: tuple
    unit: str
    low: float
    high: float
    description: str
    integer: bool = False
    vector: bool = True  # may differ between the runs of one batch (else runs are grouped)


def _from_specs(cls: type, prefix: str, root: str, scalar_only=(), integer=()) -> list[Quantity]:
    """Quantities of every non-boolean spec'd field of ``cls`` under ``prefix``."""
    out = []
    for name, f in iter_specs(cls):
        if isinstance(f.default, bool):
            continue
        m = f.metadata
        out.append(
            Quantity(
                prefix + name,
                root,
                tuple(name.split('.')),
                m['unit'],
                m['low'],
                m['high'],
                m['description'],
                integer=name in integer or isinstance(f.default, int),
                vector=not any(name == s or name.startswith(s) for s in scalar_only),
            )
        )
    return out


def quantities(controller: str) -> dict[str, Quantity]:
    """Every quantity a sweep of ``controller`` may vary, by name."""
    depth_low, depth_high = limits.ENVELOPE_DEPTH_M
    items = _from_specs(PlantParameters, '', 'plant', scalar_only=('substeps',))
    items.append(
        Quantity(
            'depth_m',
            'depth',
            (),
            'm',
            depth_low,
            depth_high,
            'water depth; sets condition.pressure_pa = rho g depth (sea water)',
        )
    )
    items += _from_specs(EsoGains, 'eso.', 'eso', scalar_only=('l1', 'l2', 'l3'))
    items += _from_specs(
        GAINS_BY_NAME[controller], f'{controller}.', 'gains', scalar_only=('ppf.',)
    )
    items += _from_specs(CommonConfig, 'common.', 'common', scalar_only=('dt_s',))
    items += [
        q
        for q in _from_specs(EncoderParameters, 'encoder.', 'encoder', integer=('counts_per_rev',))
        if q.name != 'encoder.seed'
    ]
    items.append(
        Quantity(
            'command_delay_samples',
            'delay',
            (),
            'samples',
            0.0,
            float(limits.COMMAND_DELAY_MAX_SAMPLES),
            'samples between a command and its application by the plant',
            integer=True,
        )
    )
    return {q.name: q for q in items}


def lookup(name: str, controller: str) -> Quantity:
    """Return the quantity called ``name``.

    StudyInputError naming the nearest one when there is none.
    """
    table = quantities(controller)
    if name in table:
        return table[name]
    other = [c for c in CONTROLLER_NAMES if c != controller and name.startswith(c + '.')]
    if other:
        raise StudyInputError(
            f'{name!r} is a gain of {other[0]}, but this study runs {controller} '
            f'(use --controller {other[0]})'
        )
    near = sorted((n for n in table if n.startswith(name)), key=len)[
        :1
    ] or difflib.get_close_matches(
        name, list(table), n=1, cutoff=0.5
    )  # a unit suffix left off, else a typo
    hint = f'; did you mean {near[0]!r}?' if near else ''
    raise StudyInputError(f'unknown quantity {name!r}{hint}')


@dataclass(frozen=True)
class Axis:
    """A varied quantity.

    Explicit points (grid or lists), or a range [low, high] with a point count.
    """

    name: str
    low: float = float('nan')
    high: float = float('nan')
    points: int = 0
    values: tuple = ()

    def grid_values(self) -> np.ndarray:
        """Return the grid points of this axis."""
        if self.values:
            return np.asarray(self.values, dtype=float)
        if self.points < 1:
            raise StudyInputError(
                f'{self.name}: a grid needs a point count, {self.name}=LOW:HIGH:N with N >= 1'
            )
        return np.linspace(self.low, self.high, self.points)


def _number(text: str, what: str) -> float:
    """Return a float from user text, or StudyInputError."""
    try:
        value = float(text)
    except ValueError:
        raise StudyInputError(f'{what}: {text!r} is not a number') from None
    if not np.isfinite(value):
        raise StudyInputError(f'{what}: {text!r} is not finite')
    return value


def parse_axis(text: str, controller: str) -> Axis:
    """NAME=LOW:HIGH[:N] or NAME=V1,V2,... into a checked Axis."""
    name, eq, spec_text = text.partition('=')
    name = name.strip()
    if not eq or not spec_text:
        raise StudyInputError(f'{text!r}: expected NAME=LOW:HIGH[:N] or NAME=V1,V2,...')
    q = lookup(name, controller)
    if ',' in spec_text or ':' not in spec_text:  # a list, or one value
        values = tuple(_number(v, name) for v in spec_text.split(',') if v.strip())
        if not values:
            raise StudyInputError(f'{name}: empty list of values')
        axis = Axis(name, min(values), max(values), len(values), values)
    else:
        parts = spec_text.split(':')
        if len(parts) not in (2, 3):
            raise StudyInputError(f'{name}: expected LOW:HIGH[:N], got {spec_text!r}')
        low, high = _number(parts[0], name), _number(parts[1], name)
        points = 0
        if len(parts) == 3:
            count = _number(parts[2], name)
            if count != int(count) or count < 1:
                raise StudyInputError(
                    f'{name}: point count must be a whole number >= 1, got {parts[2]!r}'
                )
            points = int(count)
        if high < low:
            raise StudyInputError(
                f'{name}: inverted range {low:g}:{high:g} (low must not exceed high)'
            )
        if high == low and points != 1:
            raise StudyInputError(
                f'{name}: empty range {low:g}:{high:g} (use --set {name}={low:g} for one value)'
            )
        axis = Axis(name, low, high, points)
    check_in_range(q, axis.low, axis.high)
    return axis


def check_in_range(q: Quantity, low: float, high: float) -> None:
    """StudyInputError when [low, high] leaves the quantity's valid range."""
    if low < q.low or high > q.high:
        unit = f' {q.unit}' if q.unit else ''
        raise StudyInputError(
            f'{q.name}: {low:g}..{high:g} leaves its valid range [{q.low:g}, {q.high:g}]{unit} '
            f'({q.description})'
        )


def parse_setting(text: str, controller: str) -> tuple[str, float]:
    """NAME=VALUE into a checked (name, value)."""
    name, eq, value_text = text.partition('=')
    if not eq:
        raise StudyInputError(f'{text!r}: expected NAME=VALUE')
    q = lookup(name.strip(), controller)
    value = _number(value_text, q.name)
    check_in_range(q, value, value)
    return q.name, value


def sample(axes: list[Axis], method: str, samples: int, seed: int) -> dict[str, np.ndarray]:
    """Return the design table: one array per axis name, one element per run."""
    if method not in METHODS:
        raise StudyInputError(f'method must be one of {", ".join(METHODS)}, got {method!r}')
    if not axes:
        raise StudyInputError('nothing to vary: give at least one --vary NAME=...')
    names = [a.name for a in axes]
    if len(set(names)) != len(names):
        raise StudyInputError(f'a quantity is varied twice: {", ".join(names)}')
    if method == 'grid':
        columns = list(zip(*itertools.product(*(a.grid_values() for a in axes))))
        return {a.name: np.asarray(c, dtype=float) for a, c in zip(axes, columns)}
    if samples < 1:
        raise StudyInputError(f'sample count must be >= 1, got {samples}')
    rng = np.random.default_rng(seed)
    table = {}
    for a in axes:
        if a.values:
            table[a.name] = rng.choice(np.asarray(a.values, dtype=float), size=samples)
            continue
        u = (
            rng.uniform(size=samples)
            if method == 'mc'
            else (rng.permutation(samples) + rng.uniform(size=samples)) / samples
        )
        table[a.name] = a.low + u * (a.high - a.low)
    return table


def check_batchable(base: 'BaseScenario', axes: list[Axis]) -> None:
    """StudyInputError for a varied quantity the vectorised loop cannot take as an array.

    Each varied vector quantity is tried with two different values in a batch of two runs
    (construction and two samples, a few ms); one that fails there, although its first value
    alone runs, is refused before anything is written (sweep it one value per study with --set).
    """
    from actuator_sim.loop import ClosedLoop

    table = quantities(base.controller)
    for axis in axes:
        q = table[axis.name]
        if not q.vector:
            continue
        values = axis.grid_values() if axis.values or axis.points else None
        low, high = (values[0], values[-1]) if values is not None else (axis.low, axis.high)
        if low == high:
            continue
        seeds = np.zeros(2, dtype=np.uint64)
        with np.errstate(all='ignore'):
            try:
                loop = ClosedLoop(
                    build_scenario(base, {axis.name: np.array([low, high])}, seeds=seeds), batch=2
                )
                loop.step()
                loop.step()
            except (TypeError, ValueError) as exc:
                try:
                    ClosedLoop(build_scenario(base, {axis.name: float(low)})).step()
                except (TypeError, ValueError):
                    continue  # fails alone too: not a batching matter (the run reports it)
                raise StudyInputError(
                    f'{axis.name} cannot vary inside a vectorised batch ({exc}); '
                    f'run one study per value with --set {axis.name}=VALUE'
                ) from None


def run_seeds(seed: int, indices: np.ndarray) -> np.ndarray:
    """Per-run noise seeds from the study seed and the run indices (independent of batching).

    63 bits of SeedSequence([seed, i]) (the encoder's seed range is [0, 2^63]): a collision
    among 1e6 runs has probability about 5e-8, where 32 bits gave several in 2e5 runs.
    """
    return np.array(
        [
            np.random.SeedSequence([seed, int(i)]).generate_state(1, dtype=np.uint64)[0] >> 1
            for i in indices
        ],
        dtype=np.uint64,
    )


@dataclass(frozen=True)
class BaseScenario:
    """What every run of a study shares.

    controller, reference, condition, duration, gains, fixed values.
    """

    controller: str = 'pp_nftsmc_eso'
    reference: str = 'fast'
    condition: str = 'deep_sea'
    duration_s: float = 10.0
    gains: Any = None
    eso: EsoGains = field(default_factory=EsoGains)
    fixed: tuple = ()  # ((name, value), ...)

    def values_with(self, varied: dict[str, Any]) -> dict[str, Any]:
        """Return the fixed values overridden by the varied ones (a name may not be both)."""
        both = set(dict(self.fixed)) & set(varied)
        if both:
            raise StudyInputError(f'{", ".join(sorted(both))} is both varied and set')
        return {**dict(self.fixed), **varied}


def _replace_nested(obj, changes: dict[tuple, Any]):
    """``obj`` with the values of ``changes`` (path tuple -> value) put in.

    Nested dataclasses rebuilt once each.
    """
    direct = {p[0]: v for p, v in changes.items() if len(p) == 1}
    inner: dict[str, dict] = {}
    for p, v in changes.items():
        if len(p) > 1:
            inner.setdefault(p[0], {})[p[1:]] = v
    for name, sub in inner.items():
        direct[name] = _replace_nested(getattr(obj, name), sub)
    return dataclasses.replace(obj, **direct) if direct else obj


def build_scenario(
    base: BaseScenario, values: dict[str, Any], seeds=None, name: str = 'study'
) -> Scenario:
    """Return the Scenario of one run (scalars) or one batch (arrays, one element per run)."""
    table = quantities(base.controller)
    values = base.values_with(values) if values is not None else dict(base.fixed)
    if 'depth_m' in values and 'condition.pressure_pa' in values:
        raise StudyInputError('depth_m sets condition.pressure_pa: give one of them')
    changes: dict[str, dict] = {'plant': {}, 'eso': {}, 'gains': {}, 'common': {}, 'encoder': {}}
    delay = 0
    for key, value in values.items():
        q = table[key]
        if q.integer:
            value = np.round(value)
            value = value.astype(int) if isinstance(value, np.ndarray) else int(value)
        if q.root == 'depth':
            changes['plant'][('condition', 'pressure_pa')] = (
                SEAWATER_DENSITY_KG_M3 * GRAVITY_M_S2 * value
            )
        elif q.root == 'delay':
            delay = value
        else:
            changes[q.root][q.path] = value
    plant = _replace_nested(
        PlantParameters(condition=CONDITIONS[base.condition]()), changes['plant']
    )
    gains = base.gains if base.gains is not None else GAINS_BY_NAME[base.controller]()
    encoder = None
    if changes['encoder']:
        encoder = _replace_nested(
            EncoderParameters(seed=0 if seeds is None else seeds), changes['encoder']
        )
    return Scenario(
        name=name,
        controller=base.controller,
        reference=base.reference,
        plant=plant,
        eso=_replace_nested(base.eso, changes['eso']),
        gains=_replace_nested(gains, changes['gains']),
        common=_replace_nested(CommonConfig(), changes['common']),
        duration_s=base.duration_s,
        encoder=encoder,
        command_delay_samples=delay,
    )
