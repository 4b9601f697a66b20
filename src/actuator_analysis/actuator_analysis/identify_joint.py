# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""One identification from records: refusals, the fits, the chosen model and its held-out fit.

``identify(records)`` runs the checks on the data first (each a ``RefusedData`` with its reason,
see ``identify``'s docstring for the thresholds), then fits every friction model, chooses one,
refuses a theta1 that the data does not determine, and simulates the held-out blocks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from actuator_core import limits

from . import identify as idf
from .identify_heldout import HeldOutFit, held_out_fit


@dataclass
class Identification:
    """What a run says about its joint."""

    chosen: idf.Fit
    fits: dict[str, idf.Fit]
    held_out: HeldOutFit
    figures: dict  # samples, duration, records, blocks, excitation figures
    regressors: idf.Regressors
    notes: list[str] = field(default_factory=list)

    @property
    def model(self) -> str:
        """The chosen friction model."""
        return self.chosen.model

    def value(self, name: str) -> float:
        """Return the chosen model's estimate of a parameter."""
        return float(self.chosen.estimate[idf.PARAMETERS[self.model].index(name)])

    def interval(self, name: str) -> tuple[float, float]:
        """Return the 95 % interval of a parameter of the chosen model."""
        i = idf.PARAMETERS[self.model].index(name)
        v, h = self.chosen.estimate[i], self.chosen.half_width[i]
        return float(v - h), float(v + h)

    def as_dict(self) -> dict:
        """Every estimate with its interval, the model choice and the fit figures (JSON)."""
        return {
            'identifiable': idf.IDENTIFIABLE,
            'friction_model': self.model,
            'estimates': self.chosen.as_dict(),
            'confidence': idf.CONFIDENCE,
            'models': {
                name: {
                    'bic': fit.bic,
                    'supported': idf.supported(fit),
                    'training_rms_rad_s2': float(np.sqrt(fit.rss / fit.rows)),
                    'estimates': fit.as_dict(),
                }
                for name, fit in self.fits.items()
            },
            'held_out': self.held_out.as_dict(),
            'data': self.figures,
            'notes': self.notes,
        }


def check_excitation(records: list[idf.Record], reg: idf.Regressors) -> dict:
    """Refuse data that cannot identify the model; return the figures the checks read."""
    samples = sum(len(r.position_rad) for r in records)
    at_limit = sum(int(np.count_nonzero(r.at_limit)) for r in records) / samples
    if at_limit > limits.SATURATED_FRACTION_LIMIT:
        raise idf.RefusedData(
            f'the current was at its limit in {100 * at_limit:.1f} % of the samples (more than '
            f"{100 * limits.SATURATED_FRACTION_LIMIT:g} %): there the joint follows the drive's "
            'limit, not the model; lower the excitation (excitation.acceleration_rad_s2, '
            'excitation.amplitude_rad)'
        )
    duration = len(reg.acceleration) * reg.dt_s
    training_blocks = len(np.unique(reg.block[reg.training]))
    held_blocks = len(np.unique(np.concatenate([p.block[p.held_out] for p in reg.parts])))
    if (
        duration < idf.MIN_DURATION_S
        or training_blocks < idf.MIN_TRAINING_BLOCKS
        or held_blocks < idf.MIN_HELD_OUT_BLOCKS
    ):
        raise idf.RefusedData(
            f'too little data: {duration:.1f} s of usable samples in {training_blocks} training '
            f'and {held_blocks} held-out blocks of {idf.BLOCK_S:g} s; at least '
            f'{idf.MIN_DURATION_S:g} s, {idf.MIN_TRAINING_BLOCKS} and {idf.MIN_HELD_OUT_BLOCKS} '
            'are needed (record the excitation scenario for 20 s or more)'
        )
    moving = np.abs(reg.velocity) > idf.MOVING_SPEED_RAD_S
    up = float(np.mean(moving & (reg.velocity > 0)))
    down = float(np.mean(moving & (reg.velocity < 0)))
    if min(up, down) < idf.MIN_DIRECTION_SHARE:
        raise idf.RefusedData(
            f'the joint moved one way only ({100 * up:.0f} % of the samples up, '
            f'{100 * down:.0f} % down; at least {100 * idf.MIN_DIRECTION_SHARE:g} % each way): '
            'Coulomb friction and a constant load cannot be told apart'
        )
    acc = reg.acceleration[reg.training]
    rms = float(np.sqrt(np.mean((acc - acc.mean()) ** 2))) if acc.size else 0.0
    if rms < idf.MIN_ACCELERATION_RMS_RAD_S2:
        raise idf.RefusedData(
            f'the joint hardly accelerated (acceleration RMS {rms:.2g} rad/s^2, below '
            f'{idf.MIN_ACCELERATION_RMS_RAD_S2:g}): a run at constant speed or at rest shows '
            'friction, not theta1; record the excitation scenario'
        )
    return {
        'records': len(reg.parts),
        'samples': samples,
        'usable_s': duration,
        'training_samples': int(np.count_nonzero(reg.training)),
        'held_out_samples': int(sum(np.count_nonzero(p.held_out) for p in reg.parts)),
        'training_blocks': training_blocks,
        'held_out_blocks': held_blocks,
        'at_limit_fraction': at_limit,
        'acceleration_rms_rad_s2': rms,
        'moving_up_fraction': up,
        'moving_down_fraction': down,
        'sample_time_s': reg.dt_s,
    }


def check_theta1(fit: idf.Fit) -> None:
    """Refuse a theta1 that is not positive or not determined to MAX_THETA1_HALF_WIDTH."""
    theta1, half = float(fit.estimate[0]), float(fit.half_width[0])
    if theta1 - half <= 0.0:
        raise idf.RefusedData(
            f'theta1 = {theta1:.4g} +- {half:.2g} rad/s^2/A is not positive: the current does not '
            'accelerate the joint forward (is the sign of the current or of the angle reversed?)'
        )
    if half > idf.MAX_THETA1_HALF_WIDTH * theta1:
        raise idf.RefusedData(
            f'theta1 is not determined: {theta1:.4g} +- {100 * half / theta1:.0f} % (95 %), more '
            f"than +-{100 * idf.MAX_THETA1_HALF_WIDTH:g} %: the run does not excite the joint's "
            'acceleration enough, or the joint changes during the run (its blocks disagree: a '
            'drifting theta1, a varying load); record the excitation scenario on a steady joint'
        )


def identify(records: list[idf.Record], cutoff_hz: float = idf.FILTER_CUTOFF_HZ) -> Identification:
    """Check the data, fit every friction model, choose one, and judge it on held-out data."""
    reg = idf.regressors(records, cutoff_hz)
    figures = check_excitation(records, reg)
    fits = {}
    for model in idf.FRICTION_MODELS:
        try:
            fits[model] = idf.fit_model(reg, model, cutoff_hz)
        except (np.linalg.LinAlgError, ValueError) as err:  # a candidate that does not converge
            if model == 'coulomb_viscous':
                raise idf.RefusedData(f'the least-squares fit failed ({err})') from None
    chosen = idf.choose_model(fits)
    check_theta1(chosen)
    figures['cutoff_hz'] = cutoff_hz
    held_out = held_out_fit(reg, chosen)
    return Identification(chosen, fits, held_out, figures, reg)
