# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Prescribed performance function and error transformation, paper eq. (8)-(12).

rho(t) = (rho0 - rho_inf) e^(-m t) + rho_inf bounds the error: -l rho < e < h rho (8).
With the normalised error eps = e / rho, the transformed error is
    z = S^-1(eps) = 1/2 ln((eps + l) / (h - eps))                      (11)
and its derivative z' = r (e' - rho' e / rho) (12) with
    r = dz/deps / rho = 1/(2 rho) (1/(eps + l) + 1/(h - eps)).
Typo resolved: the paper prints r = 1/(2 rho) (1/(z + l) - 1/(z - h)) with z where the
derivation of (11) gives eps = e/rho; ``test_ppf`` checks r against a numerical derivative.

Error outside the bounds: (11) is undefined there. The normalised error is clamped to
(-l, h) shrunk by ``BOUNDARY_MARGIN`` of the band, so z stays finite (|z| <= about 4.3 for
l = h = 1) and the controller keeps pushing back at full strength; the caller reports the
violation (``bounds_kept`` in ControllerState) instead of hiding it.

Beyond the paper, restarting the envelope: clamped outside the band, r of (12) is about
1/(margin rho), so alpha' of (24) and u saturate and stay there. Offline, 40 ms of 0 A at
t = 7 s (a drive watchdog after a controller stall) pushed the fast deep-sea run out of the
band, and the error stayed at 0.2-0.6 rad for the remaining 13 s; in real time the same
happened after 17 ms machine stalls. So when e leaves the band at t_v, the controller
restarts (8) there: rho0 becomes max(rho0, restart_margin |e| / min(l, h)) and t counts from
t_v, the paper's own start-up transient, and the same run recovered to 9.7e-4 rad within
1 s (see docs/paper-resolutions.md, 22). restart_margin = 0 keeps the paper's behaviour; a run
that never leaves the band (every paper case) is unchanged to the bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from actuator_core import xmath as xm
from actuator_core.params import spec, validate
from actuator_core.xmath import FloatOrArray

#: Fraction of the band (l + h) kept between the clamped normalised error and each bound.
BOUNDARY_MARGIN = 1.0e-4


@dataclass(frozen=True)
class PrescribedPerformance:
    """Envelope parameters of (8): rho0 > rho_inf > 0 [rad], m > 0 [1/s], l, h > 0."""

    rho0_rad: float = spec(
        0.25,
        'rho0: initial half-width of the error envelope (Table 4)',
        'rad',
        0.0,
        10.0,
        low_open=True,
    )
    rho_inf_rad: float = spec(
        0.05,
        'rho_inf: final half-width of the error envelope (Table 4)',
        'rad',
        0.0,
        10.0,
        low_open=True,
    )
    decay_rate_per_s: float = spec(
        0.5, 'm: decay rate of the envelope (Table 4)', '1/s', 0.0, 1.0e3, low_open=True
    )
    lower_scale: float = spec(
        1.0, 'l: lower bound is -l rho (Table 4)', '', 0.0, 100.0, low_open=True
    )
    upper_scale: float = spec(
        1.0, 'h: upper bound is +h rho (Table 4)', '', 0.0, 100.0, low_open=True
    )
    restart_margin: float = spec(
        2.0,
        'beyond the paper: when e leaves the envelope, restart (8) with rho0 = '
        'max(rho0, restart_margin |e| / min(l, h)); 0 never restarts',
        '',
        0.0,
        100.0,
    )

    def __post_init__(self) -> None:
        """Refuse an envelope that grows."""
        validate(self)
        if not self.rho_inf_rad <= self.rho0_rad:
            raise ValueError(
                f'rho_inf_rad ({self.rho_inf_rad}) must not exceed rho0_rad ({self.rho0_rad})'
            )

    def rho(self, t):
        """Return the envelope at time t [rad], rho of eq. (8)."""
        return (self.rho0_rad - self.rho_inf_rad) * xm.exp(
            -self.decay_rate_per_s * t
        ) + self.rho_inf_rad

    def rho_derivatives(self, t, rho0_rad=None):
        """Return (rho, rho', rho'') at t [rad, rad/s, rad/s^2].

        ``rho0_rad`` replaces rho0 after a restart.
        """
        rho0 = self.rho0_rad if rho0_rad is None else rho0_rad
        decay = (rho0 - self.rho_inf_rad) * xm.exp(-self.decay_rate_per_s * t)
        m = self.decay_rate_per_s
        return decay + self.rho_inf_rad, -m * decay, m * m * decay

    def restart_rho0(self, e):
        """rho0 of an envelope restarted at error ``e`` [rad] (module doc)."""
        needed = self.restart_margin * xm.fabs(e) / min(self.lower_scale, self.upper_scale)
        return xm.where(needed > self.rho0_rad, needed, self.rho0_rad)

    def bounds(self, t):
        """(-l rho, h rho) at t [rad]."""
        rho = self.rho(t)
        return -self.lower_scale * rho, self.upper_scale * rho


class Transformed(NamedTuple):
    """Transformed error z (11), its gain r (12) and whether e was inside the bounds (8)."""

    z: FloatOrArray
    r: FloatOrArray
    inside: FloatOrArray


def inside_band(e, rho, ppf: PrescribedPerformance):
    """Whether -l rho < e < h rho, the band of (11) (elementwise)."""
    return _in_band(e / rho, ppf)


def _in_band(eps, ppf: PrescribedPerformance):
    """Whether -l < eps < h for the normalised error eps = e / rho (elementwise)."""
    return (eps > -ppf.lower_scale) & (eps < ppf.upper_scale)


def transform_error(e, rho, ppf: PrescribedPerformance) -> Transformed:
    """Compute z = S^-1(e / rho) of (11) and r of (12), clamping e / rho into the band.

    See module doc.
    """
    lo, hi = -ppf.lower_scale, ppf.upper_scale
    eps = e / rho
    inside = _in_band(eps, ppf)
    margin = BOUNDARY_MARGIN * (hi - lo)
    eps_c = xm.clip(eps, lo + margin, hi - margin)
    z = 0.5 * xm.log((eps_c - lo) / (hi - eps_c))
    r = 0.5 / rho * (1.0 / (eps_c - lo) + 1.0 / (hi - eps_c))
    return Transformed(z, r, inside)


def inverse_transform(z, rho, ppf: PrescribedPerformance):
    """Compute e = rho S(z) with S(z) = (h e^z - l e^-z) / (e^z + e^-z), eq. (9)-(10)."""
    ez, emz = xm.exp(z), xm.exp(-z)
    return rho * (ppf.upper_scale * ez - ppf.lower_scale * emz) / (ez + emz)
