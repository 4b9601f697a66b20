# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Joint angle encoder: quantisation to counts per revolution and additive Gaussian noise.

The paper measures the joint angle exactly. A real joint reads it from an encoder, so the
simulated joint can report y = Q(q) + n instead of q, with
    Q(q) = round(q / delta) * delta,   delta = 2 pi / counts_per_rev   [rad]
(mid-tread: the reading is the centre of the count the angle lies in, error within
+-delta/2, no bias) and n ~ N(0, noise_std_rad^2), white, from a seeded generator.
counts_per_rev = 0 means no quantisation and noise_std_rad = 0 no noise; both are off by
default, and ``Encoder.measure`` is then the identity (the paper's cases stay bit-identical).
Counts are per revolution of the joint (output) shaft; an encoder on the motor shaft with
gear ratio N gives N times its own counts here.

Elementwise over arrays: counts, noise and q may be arrays of one shape (one joint per
element). ``seed`` may be one integer (one generator for the whole array) or one integer per
element (one independent stream per element, so a run's noise does not depend on which
other runs share its batch); noise is drawn in blocks of ``NOISE_BLOCK_SAMPLES`` per stream.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from actuator_core import limits
from actuator_core.params import spec, validate

#: Noise samples drawn at once per stream (one call per stream every so many samples).
NOISE_BLOCK_SAMPLES = 1024


@dataclass(frozen=True)
class EncoderParameters:
    """Encoder of the joint angle: resolution, noise and the noise seed (all off by default)."""

    counts_per_rev: float = spec(
        0,
        'encoder counts per revolution of the joint shaft; 0 = no quantisation',
        'counts/rev',
        0.0,
        limits.ENCODER_COUNTS_PER_REV_MAX,
    )
    noise_std_rad: float = spec(
        0.0,
        'standard deviation of the additive white measurement noise; 0 = none',
        'rad',
        0.0,
        limits.ENCODER_NOISE_STD_MAX_RAD,
    )
    seed: int = spec(
        0, 'seed of the noise generator (one per element when an array)', '', 0.0, 2.0**63
    )

    def __post_init__(self) -> None:
        """Refuse out-of-range values."""
        validate(self)

    @property
    def active(self) -> bool:
        """Whether the encoder changes the angle at all."""
        return bool(
            np.any(np.asarray(self.counts_per_rev) > 0)
            or np.any(np.asarray(self.noise_std_rad) > 0)
        )


class Encoder:
    """Stateful encoder.

    ``measure(q)`` returns the reading of one sample, drawing fresh noise each call.
    """

    def __init__(self, counts_per_rev=0, noise_std_rad=0.0, seed=0):
        """Quantise to ``counts_per_rev`` (0: none).

        Add N(0, ``noise_std_rad``^2) noise seeded by ``seed``.
        """
        self.parameters = EncoderParameters(counts_per_rev, noise_std_rad, seed)
        counts = np.asarray(counts_per_rev, dtype=float)
        self._quantised = bool(np.any(counts > 0))
        with np.errstate(divide='ignore'):
            self._resolution_rad = np.where(
                counts > 0, 2.0 * math.pi / np.where(counts > 0, counts, 1.0), 0.0
            )
        self._noise_std_rad = np.asarray(noise_std_rad, dtype=float)
        self._noisy = bool(np.any(self._noise_std_rad > 0))
        seeds = np.asarray(seed, dtype=np.uint64)
        self._per_element = seeds.ndim > 0
        self._generators = (
            [np.random.default_rng(int(s)) for s in seeds.ravel()]
            if self._per_element
            else [np.random.default_rng(int(seeds))]
        )
        self._block = np.empty((0, 0))
        self._column = 0

    @classmethod
    def from_parameters(cls, parameters: EncoderParameters) -> 'Encoder':
        """Return an encoder with the given parameters."""
        return cls(parameters.counts_per_rev, parameters.noise_std_rad, parameters.seed)

    @property
    def resolution_rad(self):
        """The resolution delta = 2 pi / counts_per_rev [rad] (0 where not quantised)."""
        return self._resolution_rad if self._resolution_rad.ndim else float(self._resolution_rad)

    def _noise(self, shape):
        """Unit-variance normal noise of ``shape`` for this sample."""
        if not self._per_element:
            return self._generators[0].standard_normal(shape)
        if self._column >= self._block.shape[1]:
            self._block = np.stack(
                [g.standard_normal(NOISE_BLOCK_SAMPLES) for g in self._generators]
            )
            self._column = 0
        column = self._block[:, self._column]
        self._column += 1
        return column.reshape(shape)

    def measure(self, position_rad):
        """Return y = round(q / delta) delta + noise_std n [rad], elementwise.

        q unchanged when the encoder is off.
        """
        y = position_rad
        if self._quantised:
            res = self._resolution_rad
            safe = np.where(res > 0, res, 1.0)
            y = np.where(res > 0, np.round(np.asarray(y) / safe) * safe, y)
        if self._noisy:
            y = y + self._noise_std_rad * self._noise(np.shape(position_rad))
        if np.ndim(y) == 0 and np.ndim(position_rad) == 0:
            return float(y)
        return y
