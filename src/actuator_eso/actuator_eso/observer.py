# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Third-order extended state observer, paper eq. (14)-(16), discretised by forward Euler.

Continuous observer (15), with x1_tilde = y - x1_hat:
    x1_hat' = x2_hat + l1 w0 x1_tilde
    x2_hat' = theta1n u + theta2n x2_hat + x3_hat + l2 w0^2 x1_tilde
    x3_hat' = l3 w0^3 x1_tilde
Gains by the bandwidth parametrisation (16): s^3 + l1 w0 s^2 + l2 w0^2 s + l3 w0^3 = (s + c w0)^3,
so l1 = 3c, l2 = 3c^2, l3 = c^3; the paper's c = 5 gives l = (15, 75, 125) and, with
w0 = 60 rad/s, a triple observer pole at -300 rad/s.

Discretisation: one forward-Euler step per sample from x_hat(k) with the pair (y(k), u(k)),
where u(k) is the current commanded for sample k and held over [t_k, t_k+1). This is a
decision, not a detail: with the paper's controller gains at 1 kHz the loop is only
lightly stable, and it diverges when the observer integrates u(k-1) instead of u(k), or is
discretised exactly (zero-order hold) instead of by Euler (see docs/paper-resolutions.md
and ``actuator_sim.stability``). x_hat(k+1) depends on samples up to k only, so the
observer never delays the sensor-to-command path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from actuator_core.loop_params import shared
from actuator_core.params import spec, validate


@dataclass(frozen=True)
class EsoGains:
    """Observer bandwidth w0 [rad/s], gains l1..l3 of (15)-(16) and the nominal model (3)."""

    omega0_rad_s: float = spec(
        60.0,
        'w0: observer bandwidth parameter of (15)-(16) (Table 4)',
        'rad/s',
        0.0,
        1.0e5,
        low_open=True,
    )
    l1: float = spec(15.0, 'l1 of (15)-(16) (Table 4)', '', 0.0, 1.0e4, low_open=True)
    l2: float = spec(75.0, 'l2 of (15)-(16) (Table 4)', '', 0.0, 1.0e6, low_open=True)
    l3: float = spec(125.0, 'l3 of (15)-(16) (Table 4)', '', 0.0, 1.0e9, low_open=True)
    theta1n: float = shared('theta1n')
    theta2n: float = shared('theta2n')

    def __post_init__(self) -> None:
        """Refuse gains that make (16) non-Hurwitz: all > 0 and l1*l2 > l3 (Routh)."""
        validate(self)
        if not self.l1 * self.l2 > self.l3:
            raise ValueError(
                f'l1*l2 must exceed l3 for a Hurwitz observer polynomial (16), '
                f'got l1={self.l1}, l2={self.l2}, l3={self.l3}'
            )

    @classmethod
    def from_bandwidth(
        cls, omega0_rad_s: float, pole_multiple: float = 5.0, **model
    ) -> 'EsoGains':
        """Gains placing all three poles of (16) at -pole_multiple * omega0."""
        c = pole_multiple
        return cls(omega0_rad_s=omega0_rad_s, l1=3.0 * c, l2=3.0 * c * c, l3=c**3, **model)

    @property
    def beta(self) -> tuple[float, float, float]:
        """Injection gains (l1 w0, l2 w0^2, l3 w0^3) of (15)."""
        w = self.omega0_rad_s
        return self.l1 * w, self.l2 * w * w, self.l3 * w**3


def eso_step(x1_hat, x2_hat, x3_hat, y, u, dt_s: float, gains: EsoGains):
    """One forward-Euler step of (15) from x_hat(k) with y(k), u(k); returns x_hat(k+1)."""
    beta1, beta2, beta3 = gains.beta
    x1_tilde = y - x1_hat
    return (
        x1_hat + dt_s * (x2_hat + beta1 * x1_tilde),
        x2_hat + dt_s * (gains.theta1n * u + gains.theta2n * x2_hat + x3_hat + beta2 * x1_tilde),
        x3_hat + dt_s * (beta3 * x1_tilde),
    )


def input_current_correction(du_a, steps: int, dt_s: float, gains: EsoGains):
    """Change of x_hat(k+1+steps) when u(k) of step k changes by ``du_a`` [A].

    Eq. (15) by forward Euler. The step puts dt * theta1n * du on x2_hat; each further step carries
    that change by the observer's error dynamics (d y = 0, d u = 0). Exact, since (15) is linear:
    adding the result to a state stepped with the wrong current gives the state stepped with the
    right one.
    """
    beta1, beta2, beta3 = gains.beta
    d1, d2, d3 = 0.0 * du_a, dt_s * gains.theta1n * du_a, 0.0 * du_a
    for _ in range(steps):
        d1, d2, d3 = (
            d1 + dt_s * (d2 - beta1 * d1),
            d2 + dt_s * (gains.theta2n * d2 + d3 - beta2 * d1),
            d3 - dt_s * beta3 * d1,
        )
    return d1, d2, d3


class ExtendedStateObserver:
    """Holds x_hat for the current sample; ``update`` consumes that sample's (y, u) pair."""

    def __init__(self, gains: EsoGains, dt_s: float, x_hat0=(0.0, 0.0, 0.0)):
        """Start from x_hat(0) = ``x_hat0`` (the paper starts at zero)."""
        if not (np.isfinite(dt_s) and dt_s > 0.0):
            raise ValueError(f'dt_s must be finite and > 0, got {dt_s}')
        self.gains = gains
        self.dt_s = dt_s
        self.x1_hat, self.x2_hat, self.x3_hat = x_hat0

    def update(self, y, u) -> None:
        """Advance x_hat(k) -> x_hat(k+1).

        With the measurement y(k) and the current u(k) commanded for it.
        """
        self.x1_hat, self.x2_hat, self.x3_hat = eso_step(
            self.x1_hat, self.x2_hat, self.x3_hat, y, u, self.dt_s, self.gains
        )

    def reset(self, x_hat) -> None:
        """Start again from ``x_hat`` (a new run, or a restart after a sensor discontinuity)."""
        self.x1_hat, self.x2_hat, self.x3_hat = x_hat

    def add(self, delta) -> None:
        """Add ``delta`` to x_hat.

        The exact repair of a step taken with the wrong current (``input_current_correction``).
        """
        self.x1_hat, self.x2_hat, self.x3_hat = (x + d for x, d in zip(self.state, delta))

    def correction(self, du_a, steps: int):
        """Change of x_hat ``steps`` steps after the current of a step changed by ``du_a`` [A].

        eq. (15).
        """
        return input_current_correction(du_a, steps, self.dt_s, self.gains)

    @property
    def state(self) -> tuple:
        """(x1_hat, x2_hat, x3_hat) for the current sample."""
        return self.x1_hat, self.x2_hat, self.x3_hat
