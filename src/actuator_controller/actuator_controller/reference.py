# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Reference trajectories with analytic derivatives.

The paper's slow and fast ones, step and sine, the identification run's excitation
(``actuator_controller.excitation``); and ``hold``, the commanded reference
(actuator_controller.commanded_reference): holds the joint's angle until a goal moves it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

from actuator_controller.commanded_reference import CommandedReference
from actuator_controller.excitation import ExcitationReference
from actuator_controller.reference_sample import ReferenceSample
from actuator_core import limits
from actuator_core import xmath as xm


class Reference(Protocol):
    """A reference trajectory: ``sample(t)`` gives x1d and its first two derivatives."""

    @property
    def name(self) -> str:
        """The reference's kind (a frozen dataclass's field, or a class attribute)."""

    def sample(self, t) -> ReferenceSample:
        """Return the reference at time t [s] since the start of the run."""


@dataclass(frozen=True)
class PaperTrajectory:
    """y_d = A (0.5 - cos(w t)) (1 - e^(-t/tau)), section 5.3 (A = 2 pi/9, tau = 1 s)."""

    frequency_rad_s: float
    amplitude_rad: float = 2.0 * math.pi / 9.0
    rise_time_constant_s: float = 1.0
    name: str = 'paper'

    def sample(self, t) -> ReferenceSample:
        """Product rule on f = 0.5 - cos(w t) and g = 1 - e^(-t/tau)."""
        w, tau, amp = self.frequency_rad_s, self.rise_time_constant_s, self.amplitude_rad
        f, df, ddf = 0.5 - xm.cos(w * t), w * xm.sin(w * t), w * w * xm.cos(w * t)
        decay = xm.exp(-t / tau)
        g, dg, ddg = 1.0 - decay, decay / tau, -decay / (tau * tau)
        return ReferenceSample(
            amp * f * g, amp * (df * g + f * dg), amp * (ddf * g + 2.0 * df * dg + f * ddg)
        )


def slow_trajectory() -> PaperTrajectory:
    """Return the paper's slow motion: w = pi rad/s."""
    return PaperTrajectory(frequency_rad_s=math.pi, name='slow')


def fast_trajectory() -> PaperTrajectory:
    """Return the paper's fast motion: w = 4 pi rad/s."""
    return PaperTrajectory(frequency_rad_s=4.0 * math.pi, name='fast')


@dataclass(frozen=True)
class StepReference:
    """x1d = amplitude for t >= start_s, else 0.

    Derivatives zero: the step itself is not differentiable.
    """

    amplitude_rad: float = 0.1
    start_s: float = 0.0
    name: str = 'step'

    def sample(self, t) -> ReferenceSample:
        """Step value; zero velocity and acceleration."""
        zero = 0.0 * t
        return ReferenceSample(
            xm.where(t >= self.start_s, self.amplitude_rad, 0.0) + zero, zero, zero
        )


@dataclass(frozen=True)
class SineReference:
    """x1d = offset + amplitude sin(w t)."""

    amplitude_rad: float = 0.2
    frequency_rad_s: float = 2.0 * math.pi
    offset_rad: float = 0.0
    name: str = 'sine'

    def sample(self, t) -> ReferenceSample:
        """Sine and its analytic derivatives."""
        w, amp = self.frequency_rad_s, self.amplitude_rad
        s, c = xm.sin(w * t), xm.cos(w * t)
        return ReferenceSample(self.offset_rad + amp * s, amp * w * c, -amp * w * w * s)


#: The references ``make_reference`` builds, by name: ``hold`` (commanded: goals move it) and
#: the built-in trajectories, which run from activation and take no goals.
REFERENCE_KINDS = ('hold', 'slow', 'fast', 'step', 'sine', 'excitation')


def make_reference(
    kind: str,
    amplitude_rad: float | None = None,
    frequency_rad_s: float | None = None,
    max_deceleration: tuple = (limits.STOP_DECELERATION_RAD_S2,),
    excitation=None,
) -> Reference:
    """Build a reference by name (REFERENCE_KINDS).

    An amplitude or frequency given overrides the dataclass's default (one source: the node's
    parameters default to them too). ``max_deceleration``: hold's bound on |x1d''| per joint when
    it stops a motion [rad/s^2]; ``excitation`` (an ExcitationReference) replaces the
    excitation's defaults.
    """
    amplitude: dict[str, Any] = {} if amplitude_rad is None else {'amplitude_rad': amplitude_rad}
    frequency: dict[str, Any] = (
        {} if frequency_rad_s is None else {'frequency_rad_s': frequency_rad_s}
    )
    if kind == 'hold':
        ref: Reference = CommandedReference(max_deceleration)
    elif kind == 'slow':
        ref = slow_trajectory()
    elif kind == 'fast':
        ref = fast_trajectory()
    elif kind == 'step':
        ref = StepReference(**amplitude)
    elif kind == 'sine':
        ref = SineReference(**amplitude, **frequency)
    elif kind == 'excitation':
        ref = excitation if excitation is not None else ExcitationReference()
    else:
        raise ValueError(f'reference must be one of {", ".join(REFERENCE_KINDS)}, got {kind!r}')
    return ref
