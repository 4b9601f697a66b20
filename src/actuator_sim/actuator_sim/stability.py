# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Is a gain set stable at a sample time and delay? Spectral radius of the linearised sampled loop.

The loop of ``closed_loop`` (ideal plant (5) with d = 0, forward-Euler ESO (15), controller)
is one nonlinear map X(k+1) = F(X(k)) over the state
    X = [q, q', x1_hat, x2_hat, x3_hat, controller integral, u(k-1), ..., u(k-D)],
where the plant applies u(k - plant_delay) and the ESO integrates u(k - eso_delay). Its
Jacobian at the origin, by central differences of the very functions the nodes run, is
the sampled loop's transition matrix; the loop is locally stable when every eigenvalue
lies inside the unit circle (spectral radius < 1). The PP controller is time-varying
through rho(t), so the radius is evaluated with t frozen at points along the envelope.

The plant's linear part is kept: nominal parameters and the oil's viscous stirring loss of
the working condition (linear in q'); the seal friction, external torque and drift are not
linear and are left out. Linearisation also leaves out the relay term eta sign(sigma) (set
to zero) and the current limit (set out of reach). The signed powers |z|^[alpha] of (27)
have no slope at the origin for alpha > 1 and an infinite one for alpha < 1, so they are
linearised at a stated operating amplitude A: k |z|^[alpha] -> k alpha A^(alpha - 1) z.
For PP-NFTSMC-ESO, z1 ~ e/rho(t), so its amplitude is error_amplitude/rho(t).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from typing import Sequence

import numpy as np

from actuator_controller.laws import CONTROLLER_NAMES, GAINS_BY_NAME, CommonConfig, make_controller
from actuator_controller.reference import ReferenceSample
from actuator_eso.observer import EsoGains, ExtendedStateObserver
from actuator_plant.model import JointPlant, PlantParameters

_REST = ReferenceSample(0.0, 0.0, 0.0)


def linearised_gains(gains, t_s: float, error_amplitude_rad: float, z2_amplitude_rad_s: float):
    """Return the gains with eta = 0 and the signed powers linearised.

    The signed powers are replaced by their slope at the operating amplitude.
    """
    changes: dict = {}
    if hasattr(gains, 'eta_rad_s2'):
        changes['eta_rad_s2'] = 0.0
    if hasattr(gains, 'alpha1'):
        z1_amplitude = (
            error_amplitude_rad / gains.ppf.rho(t_s)
            if hasattr(gains, 'ppf')
            else error_amplitude_rad
        )
        changes.update(
            k1=gains.k1 * gains.alpha1 * z1_amplitude ** (gains.alpha1 - 1.0),
            alpha1=1.0,
            k2=gains.k2 * gains.alpha2 * z2_amplitude_rad_s ** (gains.alpha2 - 1.0),
            alpha2=1.0,
        )
    return dataclasses.replace(gains, **changes)


def loop_jacobian(
    controller_name: str,
    gains=None,
    eso: EsoGains | None = None,
    dt_s: float = 1.0e-3,
    t_s: float = 0.0,
    plant_delay: int = 0,
    eso_delay: int = 0,
    plant: PlantParameters | None = None,
    error_amplitude_rad: float = 1.0e-3,
    z2_amplitude_rad_s: float = 1.0e-2,
) -> np.ndarray:
    """Transition matrix of the sampled loop at the origin with time frozen at ``t_s``."""
    gains = linearised_gains(
        gains if gains is not None else GAINS_BY_NAME[controller_name](),
        t_s,
        error_amplitude_rad,
        z2_amplitude_rad_s,
    )
    eso = eso or EsoGains()
    plant_params = dataclasses.replace(
        plant or PlantParameters(),
        with_drift=False,
        with_external_torque=False,
        with_seal_friction=False,
    )
    common = CommonConfig(
        theta1n=eso.theta1n, theta2n=eso.theta2n, dt_s=dt_s, current_limit_a=1.0e3
    )
    with_integral = make_controller(controller_name, gains, common).has_integral
    history = max(plant_delay, eso_delay)
    base_size = 6 if with_integral else 5
    size = base_size + history

    def one_sample(x: np.ndarray) -> np.ndarray:
        joint = JointPlant(plant_params, dt_s, position_rad=x[0], velocity_rad_s=x[1])
        observer = ExtendedStateObserver(eso, dt_s, x_hat0=(x[2], x[3], x[4]))
        controller = make_controller(controller_name, gains, common)
        if with_integral:
            controller.integral = x[5]
        y = joint.position_rad
        u_now = float(
            controller.update(t_s, y, observer.x2_hat, observer.x3_hat, _REST).current_unlimited_a
        )
        u_hist = [u_now] + list(x[base_size : base_size + history])
        observer.update(y, u_hist[eso_delay])
        joint.step(u_hist[plant_delay])
        integral = [controller.integral] if with_integral else []
        return np.array(
            [
                joint.position_rad,
                joint.velocity_rad_s,
                *observer.state,
                *integral,
                *u_hist[:history],
            ],
            dtype=float,
        )

    jac = np.zeros((size, size))
    base = np.zeros(size)
    for i in range(size):
        h = 1.0e-7
        step = np.zeros(size)
        step[i] = h
        jac[:, i] = (one_sample(base + step) - one_sample(base - step)) / (2.0 * h)
    return jac


def spectral_radius(jacobian: np.ndarray) -> float:
    """Largest eigenvalue magnitude of a transition matrix."""
    return float(np.max(np.abs(np.linalg.eigvals(jacobian))))


def radius_along_envelope(
    controller_name: str, gains=None, times_s: Sequence[float] = (0.0, 2.0, 5.0, 10.0), **kwargs
) -> list[tuple[float, float]]:
    """(t, spectral radius) at each frozen time; the worst one decides stability."""
    return [
        (t, spectral_radius(loop_jacobian(controller_name, gains, t_s=t, **kwargs)))
        for t in times_s
    ]


def drift_extremes(plant: PlantParameters, viscous: bool = True) -> list[PlantParameters]:
    """Return the vertices of the drift of eq. (41) as drift-free plants.

    J_n (1 +- a_J), k_tn (1 +- a_kt), k_bn (1 +- a_kb) with the plant's own amplitudes (8
    plants); ``viscous`` False keeps k_bn (1 - a_kb) only (4 plants). The linearised loop of a
    drifting plant is judged at the parameters it passes through.
    """
    d, n = plant.drift, plant.nominal
    out = []
    for sj in (-1.0, 1.0):
        for skt in (-1.0, 1.0):
            for skb in (-1.0, 1.0) if viscous else (-1.0,):
                nominal = dataclasses.replace(
                    n,
                    inertia_kg_m2=n.inertia_kg_m2 * (1.0 + sj * d.inertia_amplitude),
                    torque_constant_nm_a=n.torque_constant_nm_a
                    * (1.0 + skt * d.torque_constant_amplitude),
                    viscous_coefficient_nm_s_rad=n.viscous_coefficient_nm_s_rad
                    * (1.0 + skb * d.viscous_amplitude),
                )
                out.append(dataclasses.replace(plant, nominal=nominal, with_drift=False))
    return out


def largest_stable_scale(
    controller_name: str, gains, fields: Sequence[str], target_radius: float = 0.95, **kwargs
) -> float | None:
    """Largest factor s on a log grid in [1e-4, 1] that meets the target.

    That is: scaling ``fields`` by s gives radius <= target. The radius is not monotonic in s
    (small gains leave slow poles near 1), so the grid is scanned from 1 downwards; None when no
    factor reaches the target.
    """
    for scale in np.logspace(0.0, -4.0, 161):
        scaled = dataclasses.replace(gains, **{f: getattr(gains, f) * scale for f in fields})
        if (
            max(r for _, r in radius_along_envelope(controller_name, scaled, **kwargs))
            <= target_radius
        ):
            return float(scale)
    return None


def _parse_overrides(items: Sequence[str], gains):
    """Apply NAME=VALUE overrides to a gains dataclass."""
    values = {}
    for item in items:
        name, _, text = item.partition('=')
        if name not in {f.name for f in dataclasses.fields(gains)}:
            raise SystemExit(
                f'stability_check: {name!r} is not a gain of this controller '
                f'({", ".join(f.name for f in dataclasses.fields(gains))})'
            )
        values[name] = float(text)
    return dataclasses.replace(gains, **values)


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: print the spectral radius along the envelope and whether the gain set is stable."""
    parser = argparse.ArgumentParser(prog='stability_check', description=__doc__.splitlines()[0])
    parser.add_argument('--controller', choices=CONTROLLER_NAMES, default='pp_nftsmc_eso')
    parser.add_argument(
        '--set', nargs='*', default=[], metavar='GAIN=VALUE', help='override Table 4 gains'
    )
    parser.add_argument('--dt', type=float, default=1.0e-3, help='sample time [s]')
    parser.add_argument(
        '--plant-delay', type=int, default=0, help='samples between command and its application'
    )
    parser.add_argument(
        '--eso-delay',
        type=int,
        default=0,
        help='samples by which the ESO current lags the command',
    )
    parser.add_argument(
        '--times',
        type=float,
        nargs='*',
        default=[0.0, 1.0, 2.0, 5.0, 10.0],
        help='frozen times [s]',
    )
    parser.add_argument('--json', action='store_true', help='print JSON instead of a table')
    args = parser.parse_args(argv)
    if args.plant_delay < 0 or args.eso_delay < 0 or not args.dt > 0:
        parser.error('delays must be >= 0 and dt > 0')
    gains = _parse_overrides(args.set, GAINS_BY_NAME[args.controller]())
    rows = radius_along_envelope(
        args.controller,
        gains,
        args.times,
        dt_s=args.dt,
        plant_delay=args.plant_delay,
        eso_delay=args.eso_delay,
    )
    worst = max(r for _, r in rows)
    if args.json:
        print(
            json.dumps(
                {
                    'controller': args.controller,
                    'gains': dataclasses.asdict(gains),
                    'dt_s': args.dt,
                    'plant_delay': args.plant_delay,
                    'eso_delay': args.eso_delay,
                    'radius': [{'t_s': t, 'spectral_radius': r} for t, r in rows],
                    'stable': worst < 1.0,
                },
                default=str,
            )
        )
    else:
        print(
            f'{args.controller} at dt = {args.dt * 1e3:g} ms, plant delay {args.plant_delay}, '
            f'ESO delay {args.eso_delay} samples'
        )
        for t, r in rows:
            print(f'  t = {t:6.2f} s   spectral radius {r:.6f}')
        print(f'  {"STABLE" if worst < 1.0 else "UNSTABLE"} (worst radius {worst:.6f})')
    return 0 if worst < 1.0 else 1


if __name__ == '__main__':
    sys.exit(main())
