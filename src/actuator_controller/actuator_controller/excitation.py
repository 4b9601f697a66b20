# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The identification run's reference: constant-speed sweeps for friction, a multi-sine for theta1.

One cycle is four segments, repeated for as long as the run lasts:
  1-3. triangle sweeps between +-A_r at 1/4, 1/2 and all of ``sweep_velocity_rad_s`` (one period
       each: both directions at constant speed, the quasistatic test of a friction curve), the
       turns a half cosine of the velocity at the acceleration bound;
  4.   a multi-sine of ``MULTISINE_COMPONENTS`` log-spaced harmonics of ``low_frequency_hz`` up to
       ``high_frequency_hz`` (Schroeder phases, for a low crest factor), each component's
       amplitude the smaller of a flat position and a flat acceleration spectrum, the sum scaled
       so that its peak angle, speed and acceleration stay inside the bounds (two periods).
Each segment fades in and out over ``FADE_S`` with a quintic smoothstep w: x1d = w s, so the angle
and its first two derivatives are continuous and the joint passes through rest at 0 between
segments (x1d(0) = 0 at rest: the run starts where the joint is). Bounds: |x1d| <= amplitude_rad
(inside the soft limits when the amplitude is), |x1d''| <= acceleration_rad_s2 on the plateaus,
whose default is ``limits.EXCITATION_ACCELERATION_RAD_S2``, a quarter of what the current limit
commands with the nominal model; the fades add at most a few tens of rad/s^2 (test).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from actuator_controller.reference_sample import ReferenceSample
from actuator_core import limits
from actuator_core.params import spec, validate

#: Duration of each segment's fade in and fade out [s].
FADE_S = 0.25
#: Speeds of the three sweeps, as fractions of sweep_velocity_rad_s.
SWEEP_SPEED_FRACTIONS = (0.25, 0.5, 1.0)
#: Sine components of the multi-sine and how many of its periods a cycle holds.
MULTISINE_COMPONENTS = 12
MULTISINE_PERIODS = 2
#: Points per period of the highest component where the multi-sine's peaks are found, and the
#: margin its scale keeps below the bounds: between grid points a peak rises at most by about
#: (pi / points)^2 / 2 = 3e-4 of itself.
PEAK_GRID_PER_PERIOD = 128
PEAK_MARGIN = 1.0e-3


def smoothstep(u: float) -> tuple[float, float, float]:
    """Quintic smoothstep w(u) = 10u^3 - 15u^4 + 6u^5 on [0, 1] with dw/du, d2w/du2."""
    u = min(max(u, 0.0), 1.0)
    return (
        u * u * u * (10.0 + u * (-15.0 + 6.0 * u)),
        30.0 * u * u * (1.0 - u) ** 2,
        60.0 * u * (1.0 - u) * (1.0 - 2.0 * u),
    )


@dataclass(frozen=True)
class ExcitationReference:
    """Sweeps and a multi-sine for ``bag_identify`` (module docstring); parameters are specs."""

    amplitude_rad: float = spec(
        0.5,
        'excitation: largest |x1d| (keep it inside the joint soft limits around the start angle)',
        'rad',
        0.0,
        10.0,
        low_open=True,
    )
    low_frequency_hz: float = spec(
        0.5, 'excitation: lowest multi-sine frequency (its period 1/this)', 'Hz', 0.05, 50.0
    )
    high_frequency_hz: float = spec(
        8.0, 'excitation: highest multi-sine frequency', 'Hz', 0.1, 100.0
    )
    sweep_velocity_rad_s: float = spec(
        2.0,
        'excitation: speed of the fastest constant-speed sweep (the others 1/4 and 1/2 of it)',
        'rad/s',
        0.0,
        limits.EXCITATION_VELOCITY_RAD_S,
        low_open=True,
    )
    acceleration_rad_s2: float = spec(
        limits.EXCITATION_ACCELERATION_RAD_S2,
        "excitation: largest |x1d''| of the sweeps and the multi-sine (the current it takes is "
        'about this / theta1)',
        'rad/s^2',
        0.0,
        limits.CURRENT_ACCELERATION_RAD_S2,
        low_open=True,
    )
    name: str = 'excitation'

    def __post_init__(self) -> None:
        """Refuse a band that is empty or too wide, and sweeps that overshoot the amplitude."""
        validate(self)
        ratio = self.high_frequency_hz / self.low_frequency_hz
        if not 1.0 < ratio <= 200.0:
            raise ValueError(
                f'excitation: high_frequency_hz / low_frequency_hz must be in (1, 200], got '
                f'{self.high_frequency_hz:g} / {self.low_frequency_hz:g}'
            )
        v = self.sweep_velocity_rad_s
        if v * v / self.acceleration_rad_s2 >= 0.5 * self.amplitude_rad:
            raise ValueError(
                f'excitation: a sweep at {v:g} rad/s turning at {self.acceleration_rad_s2:g} '
                f'rad/s^2 overshoots by v^2/a = {v * v / self.acceleration_rad_s2:.3g} rad, '
                f'more than half of amplitude_rad = {self.amplitude_rad:g}: lower the speed'
            )

    @functools.cached_property
    def _segments(self) -> tuple:
        """(start, plateau duration, kind, speed) per segment, and the cycle length [s]."""
        segments, start = [], 0.0
        for fraction in SWEEP_SPEED_FRACTIONS:
            v = fraction * self.sweep_velocity_rad_s
            half, turn = self._sweep_geometry(v)
            plateau = 4.0 * half / v + 2.0 * turn
            segments.append((start, plateau, 'sweep', v))
            start += plateau + 2.0 * FADE_S
        plateau = MULTISINE_PERIODS / self.low_frequency_hz
        segments.append((start, plateau, 'multisine', 0.0))
        return tuple(segments), start + plateau + 2.0 * FADE_S

    @property
    def cycle_s(self) -> float:
        """Duration of one cycle of the four segments [s]."""
        return self._segments[1]

    def _sweep_geometry(self, v: float) -> tuple[float, float]:
        """Half-length A_r of a sweep's constant-speed leg [rad] and its turn time [s]."""
        turn = math.pi * v / self.acceleration_rad_s2  # a half cosine of the velocity, peak a
        return self.amplitude_rad - v * turn / math.pi, turn

    @functools.cached_property
    def _multisine(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Frequencies [rad/s], amplitudes [rad] and phases of the multi-sine's components."""
        ratio = self.high_frequency_hz / self.low_frequency_hz
        harmonics = np.unique(np.round(np.geomspace(1.0, ratio, MULTISINE_COMPONENTS)))
        w = 2.0 * math.pi * self.low_frequency_hz * harmonics
        corner = math.sqrt(self.acceleration_rad_s2 / self.amplitude_rad)  # a = A w^2 there
        amplitude = 1.0 / np.maximum(w, corner) ** 2
        j = np.arange(len(w))
        phase = -math.pi * j * (j + 1) / len(w)  # Schroeder
        period = 1.0 / self.low_frequency_hz
        t = np.linspace(0.0, period, int(PEAK_GRID_PER_PERIOD * ratio) + 1)
        arg = np.outer(t, w) + phase
        peaks = [
            np.max(np.abs(np.sin(arg) @ amplitude)),
            np.max(np.abs(np.cos(arg) @ (amplitude * w))),
            np.max(np.abs(np.sin(arg) @ (amplitude * w * w))),
        ]
        scale = (1.0 - PEAK_MARGIN) * min(
            self.amplitude_rad / peaks[0],
            limits.EXCITATION_VELOCITY_RAD_S / peaks[1],
            self.acceleration_rad_s2 / peaks[2],
        )
        return w, amplitude * scale, phase

    def _sweep(self, tau: float, v: float) -> tuple[float, float, float]:
        """Triangle sweep at speed v, tau [s] after it passed 0 upwards: x, x', x''."""
        half, turn = self._sweep_geometry(v)
        leg = 2.0 * half / v
        s = (tau + half / v) % (2.0 * leg + 2.0 * turn)  # from -A_r, moving up
        if s < leg:
            return -half + v * s, v, 0.0
        if s < leg + turn:
            p = math.pi * (s - leg) / turn
            return (
                half + v * turn / math.pi * math.sin(p),
                v * math.cos(p),
                -v * math.pi / turn * (math.sin(p)),
            )
        if s < 2.0 * leg + turn:
            return half - v * (s - leg - turn), -v, 0.0
        p = math.pi * (s - 2.0 * leg - turn) / turn
        return (
            -half - v * turn / math.pi * math.sin(p),
            -v * math.cos(p),
            v * math.pi / turn * (math.sin(p)),
        )

    def _multi(self, tau: float) -> tuple[float, float, float]:
        """Return the multi-sine at tau [s]: x, x', x''."""
        w, amplitude, phase = self._multisine
        x = v = a = 0.0
        for wk, ak, pk in zip(w.tolist(), amplitude.tolist(), phase.tolist()):
            s, c = math.sin(wk * tau + pk), math.cos(wk * tau + pk)
            x += ak * s
            v += ak * wk * c
            a -= ak * wk * wk * s
        return x, v, a

    def _scalar(self, t: float) -> tuple[float, float, float]:
        """x1d, x1d', x1d'' at one time t >= 0 [s]."""
        segments, cycle = self._segments
        tau = float(t) % cycle
        for start, plateau, kind, v in segments:
            if tau < start + plateau + 2.0 * FADE_S:
                break
        local = tau - start
        if local < FADE_S:
            w, dw, ddw = smoothstep(local / FADE_S)
        else:
            w, dw, ddw = smoothstep((start + plateau + 2.0 * FADE_S - tau) / FADE_S)
            dw = -dw
        dw, ddw = dw / FADE_S, ddw / (FADE_S * FADE_S)
        x, dx, ddx = self._sweep(local - FADE_S, v) if kind == 'sweep' else self._multi(local)
        return w * x, dw * x + w * dx, ddw * x + 2.0 * dw * dx + w * ddx

    def sample(self, t):
        """x1d, x1d', x1d'' at t [s] (a float, or an array of times elementwise)."""
        if np.ndim(t) == 0:
            return ReferenceSample(*self._scalar(t))
        rows = np.array([self._scalar(x) for x in np.ravel(t)]).reshape(*np.shape(t), 3)
        return ReferenceSample(rows[..., 0], rows[..., 1], rows[..., 2])
