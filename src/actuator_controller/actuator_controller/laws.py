# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The paper's four joint controllers behind one interface.

PP-NFTSMC-ESO (19)-(35), NFTSMC-ESO (47)-(49)/(A9)-(A13), SMC-ESO (44)-(46)/(A1)-(A5) and
PI (43).

Each controller is called once per sample with the measured angle y(k), the observer's
x2_hat(k), x3_hat(k) and the reference; it returns the current u(k) and every intermediate
term, then advances its own integral state to sample k+1 (forward Euler, like the ESO).

Resolutions of the paper's gaps, by equation (docs/paper-resolutions.md lists them all):
* (28)-(29): sigma' is obtained from the observer's x2_hat' of (15), so the injection term
  is l2 w0^2 x1_tilde (the paper prints x2_tilde in (29)); the control law is unchanged.
* alpha' in (33): differentiated analytically, alpha' = -k0 z1' + x1d'' + (rho'' e + rho' e')/rho
  - rho'^2 e/rho^2 with z1' = r (e' - rho' e/rho) from (22), the unmeasured e' = x2 - x1d'
  replaced by x2_hat - x1d' (no velocity sensor). A backward difference of alpha makes the
  paper's loop diverge at 1 kHz.
* (27) asks 0 < alpha1 < 1 < ... but Table 4 uses alpha1 = 1.1, alpha2 = 1.3. The powers only
  enter the integrand of the sliding variable, so no singularity arises for any alpha > 0;
  Table 4's values are the defaults and any value in (0, 3] is accepted.
* (49)/(A13) use k2 in u_sw although Table 4 lists a k3 = 200 for NFTSMC-ESO that would
  otherwise be unused, and the paper says PP-NFTSMC-ESO inherits NFTSMC-ESO's gains, whose
  (34) uses k3: NFTSMC-ESO's u_sw is eta sign(sigma) + k3 sigma here.
* sign(0) = 0 (the switching term vanishes exactly on the surface).
* u_b of (35) at sigma = 0: tanh^2(sigma/tau)/sigma -> sigma/tau^2 -> 0, so u_b(0) = 0; near
  zero the series 2|z1 z2| sigma/tau^2 is used. (Lemma 1 as printed, lim tanh(B/tau)/B = 0,
  is wrong; the limit is 1/tau. The limit that (35) needs, tanh^2(B/tau)/B -> 0, holds.)
* Current limit: |u| <= current_limit_a on every controller; an integral state is frozen in
  a sample where the command is saturated and integrating would drive it further into the
  limit (conditional integration), so no integral winds up.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

from actuator_controller.ppf import PrescribedPerformance, inside_band, transform_error
from actuator_controller.reference import ReferenceSample
from actuator_core import limits
from actuator_core import xmath as xm
from actuator_core.loop_params import shared
from actuator_core.params import spec, validate
from actuator_core.xmath import FloatOrArray

CONTROLLER_NAMES = ('pp_nftsmc_eso', 'nftsmc_eso', 'smc_eso', 'pi')

NAN = float('nan')


@dataclass(frozen=True)
class CommonConfig:
    """What every controller shares.

    The nominal model (3), the sample time and the current limit.
    """

    theta1n: float = shared('theta1n')
    theta2n: float = shared('theta2n')
    dt_s: float = spec(
        limits.SAMPLE_TIME_S, 'sample time of the control loop', 's', *limits.SAMPLE_TIME_RANGE_S
    )
    current_limit_a: float = spec(
        limits.CURRENT_LIMIT_A,
        'the commanded current is limited to +-this value',
        'A',
        *limits.CURRENT_LIMIT_RANGE_A,
        low_open=True,
    )

    def __post_init__(self) -> None:
        """Refuse out-of-range values."""
        validate(self)


@dataclass(frozen=True)
class PiGains:
    """PI gains of eq. (43), Table 4."""

    kp_a_rad: float = spec(500.0, 'k_p: proportional gain (Table 4)', 'A/rad', 0.0, 1.0e6)
    ki_a_rad_s: float = spec(300.0, 'k_i: integral gain (Table 4)', 'A/(rad s)', 0.0, 1.0e7)

    def __post_init__(self) -> None:
        """Refuse out-of-range values."""
        validate(self)


@dataclass(frozen=True)
class SmcGains:
    """SMC-ESO gains of eq. (44)-(46), Table 4."""

    k1_per_s: float = spec(
        20000.0, 'k1: surface slope, sigma = z2 + k1 z1 (A1)', '1/s', 0.0, 1.0e6, low_open=True
    )
    k2_per_s: float = spec(10000.0, 'k2: linear reaching gain of u_sw (46)', '1/s', 0.0, 1.0e6)
    eta_rad_s2: float = spec(100.0, 'eta: switching gain of u_sw (46)', 'rad/s^2', 0.0, 1.0e6)

    def __post_init__(self) -> None:
        """Refuse out-of-range values."""
        validate(self)


@dataclass(frozen=True)
class NftsmcGains:
    """NFTSMC-ESO gains of eq. (47)-(49), (A9), Table 4 (u_sw uses k3, see module docstring)."""

    k1: float = spec(
        1000.0, 'k1: weight of |z1|^[alpha1] in the sliding integral (27)/(A9)', '', 0.0, 1.0e7
    )
    k2: float = spec(
        20.0, 'k2: weight of |z2|^[alpha2] in the sliding integral (27)/(A9)', '', 0.0, 1.0e7
    )
    k3_per_s: float = spec(200.0, 'k3: linear reaching gain of u_sw (34)', '1/s', 0.0, 1.0e6)
    alpha1: float = spec(1.1, 'alpha1: power on z1 (Table 4)', '', 0.0, 3.0, low_open=True)
    alpha2: float = spec(1.3, 'alpha2: power on z2 (Table 4)', '', 0.0, 3.0, low_open=True)
    eta_rad_s2: float = spec(0.1, 'eta: switching gain of u_sw (34)', 'rad/s^2', 0.0, 1.0e6)

    def __post_init__(self) -> None:
        """Refuse out-of-range values."""
        validate(self)


@dataclass(frozen=True)
class PpNftsmcGains(NftsmcGains):
    """PP-NFTSMC-ESO gains.

    NFTSMC-ESO's, which the paper says it inherits, plus (23), (35) and the envelope (8).
    """

    k0_per_s: float = spec(
        100.0, 'k0: virtual-control gain of (23)', 'rad/s', 0.0, 1.0e6, low_open=True
    )
    tau_rad_s: float = spec(
        0.06, 'tau: width of the tanh in u_b (35)', 'rad/s', 0.0, 1.0e3, low_open=True
    )
    ppf: PrescribedPerformance = field(default_factory=PrescribedPerformance)


class ControlOutput(NamedTuple):
    """Everything a controller computed for one sample (NaN where a term does not apply)."""

    current_a: FloatOrArray
    current_unlimited_a: FloatOrArray
    saturated: FloatOrArray
    error_rad: FloatOrArray
    rho_rad: FloatOrArray
    lower_bound_rad: FloatOrArray
    upper_bound_rad: FloatOrArray
    bounds_kept: FloatOrArray
    z1: FloatOrArray
    z2_rad_s: FloatOrArray
    alpha_rad_s: FloatOrArray
    alpha_dot_rad_s2: FloatOrArray
    sigma_rad_s: FloatOrArray
    u_eq_rad_s2: FloatOrArray
    u_sw_rad_s2: FloatOrArray
    u_b_rad_s2: FloatOrArray
    proportional_a: FloatOrArray
    integral_a: FloatOrArray
    finite: FloatOrArray


def signed_power(z, alpha: float):
    """|z|^[alpha] = |z|^alpha sign(z), the notation of (27)."""
    return xm.sign(z) * xm.fabs(z) ** alpha


def tanh_sq_over(sigma, tau: float):
    """tanh^2(sigma/tau)/sigma of (35), continuous at sigma = 0 (limit 0, series sigma/tau^2)."""
    small = xm.fabs(sigma) < 1.0e-9 * tau
    safe = xm.where(small, 1.0, sigma)
    return xm.where(small, sigma / (tau * tau), xm.tanh(sigma / tau) ** 2 / safe)


class Controller:
    """Base.

    Limit the current, guard non-finite output, integrate one scalar state with anti-windup.
    """

    name = ''
    #: Sign of d(current)/d(integral state);
    #: decides which integration drives further into saturation.
    integral_current_sign = -1.0
    #: Whether the controller has an integral state at all.
    has_integral = True

    def __init__(self, gains, common: CommonConfig):
        """Hold the gains (the subclass' gains dataclass); the integral state starts at zero."""
        self.gains = gains
        self.common = common
        self.integral = 0.0

    def reset(self) -> None:
        """Zero the integral state (a new run)."""
        self.integral = 0.0

    def update(self, t, y, x2_hat, x3_hat, ref: ReferenceSample) -> ControlOutput:
        """Compute the current for this sample (each law its own)."""
        raise NotImplementedError

    def _finish(self, u_unlimited, integrand, **terms) -> ControlOutput:
        """Limit u, decide the integral update (frozen on wind-up or non-finite output).

        Pack the output.
        """
        limit = self.common.current_limit_a
        finite = xm.isfinite(u_unlimited)
        u = xm.where(finite, xm.clip(xm.where(finite, u_unlimited, 0.0), -limit, limit), 0.0)
        high = u_unlimited > limit
        low = u_unlimited < -limit
        push = self.integral_current_sign * integrand
        winding = (high & (push > 0)) | (low & (push < 0))
        integrate = finite & xm.logical_not(winding)
        self.integral = xm.where(
            integrate, self.integral + self.common.dt_s * integrand, self.integral
        )
        return ControlOutput(
            current_a=u,
            current_unlimited_a=u_unlimited,
            saturated=(high | low) & finite,
            finite=finite,
            **terms,
        )

    def _finish_sliding(
        self, u_unlimited, integrand, z1, z2, ref: ReferenceSample, sigma, u_eq, u_sw
    ) -> ControlOutput:
        """``_finish`` for a sliding law without an envelope (SMC-ESO, NFTSMC-ESO)."""
        return self._finish(
            u_unlimited,
            integrand,
            error_rad=z1,
            rho_rad=NAN,
            lower_bound_rad=NAN,
            upper_bound_rad=NAN,
            bounds_kept=True,
            z1=z1,
            z2_rad_s=z2,
            alpha_rad_s=ref.velocity_rad_s,
            alpha_dot_rad_s2=ref.acceleration_rad_s2,
            sigma_rad_s=sigma,
            u_eq_rad_s2=u_eq,
            u_sw_rad_s2=u_sw,
            u_b_rad_s2=NAN,
            proportional_a=NAN,
            integral_a=NAN,
        )


class PiController(Controller):
    """u = kp (x1d - y) + ki int (x1d - y) dt, eq. (43); measurement only, no observer."""

    name = 'pi'
    gains: PiGains
    integral_current_sign = 1.0

    def update(self, t, y, x2_hat, x3_hat, ref: ReferenceSample) -> ControlOutput:
        """Compute the current for this sample; the integral advances by (x1d - y) dt."""
        e = y - ref.position_rad
        proportional = self.gains.kp_a_rad * (-e)
        integral = self.gains.ki_a_rad_s * self.integral
        return self._finish(
            proportional + integral,
            -e,
            error_rad=e,
            rho_rad=NAN,
            lower_bound_rad=NAN,
            upper_bound_rad=NAN,
            bounds_kept=True,
            z1=e,
            z2_rad_s=NAN,
            alpha_rad_s=NAN,
            alpha_dot_rad_s2=NAN,
            sigma_rad_s=NAN,
            u_eq_rad_s2=NAN,
            u_sw_rad_s2=NAN,
            u_b_rad_s2=NAN,
            proportional_a=proportional,
            integral_a=integral,
        )


class SmcEsoController(Controller):
    """SMC-ESO, eq. (44)-(46): sigma = z2 + k1 z1, u = -(u_eq + u_sw)/theta1n."""

    name = 'smc_eso'
    gains: SmcGains
    has_integral = False

    def update(self, t, y, x2_hat, x3_hat, ref: ReferenceSample) -> ControlOutput:
        """Compute the current for this sample."""
        g, c = self.gains, self.common
        z1 = y - ref.position_rad
        z2 = x2_hat - ref.velocity_rad_s
        sigma = z2 + g.k1_per_s * z1
        u_eq = c.theta2n * x2_hat + x3_hat + g.k1_per_s * z2 - ref.acceleration_rad_s2
        u_sw = g.eta_rad_s2 * xm.sign(sigma) + g.k2_per_s * sigma
        return self._finish_sliding(
            -(u_eq + u_sw) / c.theta1n, 0.0 * z1, z1, z2, ref, sigma, u_eq, u_sw
        )


class NftsmcEsoController(Controller):
    """NFTSMC-ESO, eq. (47)-(49): sigma = z2 + int(k1 |z1|^[a1] + k2 |z2|^[a2]) dt."""

    name = 'nftsmc_eso'
    gains: NftsmcGains

    def update(self, t, y, x2_hat, x3_hat, ref: ReferenceSample) -> ControlOutput:
        """Compute the current for this sample.

        The sliding integral advances by its integrand times dt.
        """
        g, c = self.gains, self.common
        z1 = y - ref.position_rad
        z2 = x2_hat - ref.velocity_rad_s
        integrand = g.k1 * signed_power(z1, g.alpha1) + g.k2 * signed_power(z2, g.alpha2)
        sigma = z2 + self.integral
        u_eq = c.theta2n * x2_hat + x3_hat - ref.acceleration_rad_s2 + integrand
        u_sw = g.eta_rad_s2 * xm.sign(sigma) + g.k3_per_s * sigma
        return self._finish_sliding(
            -(u_eq + u_sw) / c.theta1n, integrand, z1, z2, ref, sigma, u_eq, u_sw
        )


class PpNftsmcEsoController(Controller):
    """PP-NFTSMC-ESO, eq. (19)-(35): PPF-transformed error, backstepping, NFTSMC with u_b."""

    name = 'pp_nftsmc_eso'
    gains: PpNftsmcGains

    def __init__(self, gains, common: CommonConfig):
        """Start the envelope (8) at t = 0 with the gains' rho0 (until a restart, see ppf)."""
        super().__init__(gains, common)
        self.envelope_start_s = 0.0
        self.envelope_rho0_rad = gains.ppf.rho0_rad
        self.envelope_restarts = 0

    def reset(self) -> None:
        """Return a new run: zero integral, the gains' envelope from t = 0."""
        super().reset()
        self.envelope_start_s, self.envelope_rho0_rad, self.envelope_restarts = (
            0.0,
            self.gains.ppf.rho0_rad,
            0,
        )

    def update(self, t, y, x2_hat, x3_hat, ref: ReferenceSample) -> ControlOutput:
        """Compute the current for this sample.

        The sliding integral of (27) advances by its integrand times dt.
        """
        g, c = self.gains, self.common
        e = y - ref.position_rad  # (19)
        rho, rho_d, rho_dd = g.ppf.rho_derivatives(
            t - self.envelope_start_s, self.envelope_rho0_rad
        )
        tr = transform_error(e, rho, g.ppf)  # (21), r of (12)
        # Kept: inside (8) as the gains set it from the run's start, the bounds reported. A
        # restarted envelope holds the law together (resolution 22) but is no performance kept:
        # outside the gains' own the status says RECOVERING, however wide the restarted one is.
        rho_gains = g.ppf.rho(t)
        bounds_kept = tr.inside & inside_band(e, rho_gains, g.ppf)
        if g.ppf.restart_margin > 0.0 and not xm.all_true(
            tr.inside
        ):  # left the envelope: restart (8) at t
            self.envelope_start_s = xm.where(tr.inside, self.envelope_start_s, t)
            self.envelope_rho0_rad = xm.where(
                tr.inside, self.envelope_rho0_rad, g.ppf.restart_rho0(e)
            )
            self.envelope_restarts += 1
            rho, rho_d, rho_dd = g.ppf.rho_derivatives(
                t - self.envelope_start_s, self.envelope_rho0_rad
            )
            tr = transform_error(e, rho, g.ppf)
        z1 = tr.z
        alpha = -g.k0_per_s * z1 + ref.velocity_rad_s + rho_d * e / rho  # (23)
        e_dot_hat = x2_hat - ref.velocity_rad_s
        z1_dot = tr.r * (e_dot_hat - rho_d * e / rho)  # (22) with x2_hat
        alpha_dot = (
            -g.k0_per_s * z1_dot
            + ref.acceleration_rad_s2
            + (rho_dd * e + rho_d * e_dot_hat) / rho
            - rho_d * rho_d * e / (rho * rho)
        )
        z2 = x2_hat - alpha  # (20)
        integrand = g.k1 * signed_power(z1, g.alpha1) + g.k2 * signed_power(z2, g.alpha2)
        sigma = z2 + self.integral  # (27)
        u_eq = c.theta2n * x2_hat + x3_hat - alpha_dot + integrand  # (33)
        u_sw = g.eta_rad_s2 * xm.sign(sigma) + g.k3_per_s * sigma  # (34)
        u_b = 2.0 * xm.fabs(z1 * z2) * tanh_sq_over(sigma, g.tau_rad_s)  # (35)
        lower, upper = -g.ppf.lower_scale * rho_gains, g.ppf.upper_scale * rho_gains
        return self._finish(
            -(u_eq + u_sw + u_b) / c.theta1n,
            integrand,
            error_rad=e,
            rho_rad=rho,
            lower_bound_rad=lower,
            upper_bound_rad=upper,
            bounds_kept=bounds_kept,
            z1=z1,
            z2_rad_s=z2,
            alpha_rad_s=alpha,
            alpha_dot_rad_s2=alpha_dot,
            sigma_rad_s=sigma,
            u_eq_rad_s2=u_eq,
            u_sw_rad_s2=u_sw,
            u_b_rad_s2=u_b,
            proportional_a=NAN,
            integral_a=NAN,
        )


GAINS_BY_NAME = {
    'pi': PiGains,
    'smc_eso': SmcGains,
    'nftsmc_eso': NftsmcGains,
    'pp_nftsmc_eso': PpNftsmcGains,
}
CLASS_BY_NAME = {
    'pi': PiController,
    'smc_eso': SmcEsoController,
    'nftsmc_eso': NftsmcEsoController,
    'pp_nftsmc_eso': PpNftsmcEsoController,
}


def make_controller(name: str, gains=None, common: CommonConfig | None = None) -> Controller:
    """Build a controller by name with ``gains`` (default: Table 4) and ``common`` settings."""
    if name not in CLASS_BY_NAME:
        raise ValueError(f'controller must be one of {", ".join(CONTROLLER_NAMES)}, got {name!r}')
    return CLASS_BY_NAME[name](
        gains if gains is not None else GAINS_BY_NAME[name](), common or CommonConfig()
    )
