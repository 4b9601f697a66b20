# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Helpers of the identification tests (not collected): joints of known truth, and their bags.

``synthetic_joint`` runs a joint of the identified model's own family, q'' = theta1 i + theta2 q'
- fc sign(q') - fs exp(-(q'/vs)^2) sign(q') - fd q'|q'| + c, in a closed loop (a PD law with
acceleration feed-forward on the excitation reference), integrated by RK4 with the current held
over each 1 ms sample, its angle quantised as an encoder would. Every parameter's truth is then
exact. ``write_identification_bag`` writes such a run as the project's recorder or as
``ros2 bag record`` would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from actuator_analysis.identify import Record
from actuator_controller.excitation import ExcitationReference

DT_S = 1.0e-3
#: The PD law of the synthetic loop: natural frequency [rad/s] and damping, on a nominal theta1.
LOOP_RAD_S, LOOP_DAMPING, LOOP_THETA1 = 60.0, 0.9, 30.0


@dataclass
class Truth:
    """A joint of the model's family."""

    theta1: float = 25.0
    theta2: float = -8.0
    coulomb_rad_s2: float = 15.0
    offset_rad_s2: float = 2.0
    drag_per_rad: float = 0.5
    stribeck_rad_s2: float = 0.0
    stribeck_velocity_rad_s: float = 0.3
    #: theta1 (1 + a sin(w t)): a drifting joint (a, w [rad/s]); 0: constant.
    theta1_drift: tuple = (0.0, 0.0)

    def acceleration(self, t: float, v: float, i: float) -> float:
        """Return q'' of the joint."""
        a, w = self.theta1_drift
        sign = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
        friction = sign * (
            self.coulomb_rad_s2
            + self.stribeck_rad_s2 * math.exp(-((v / self.stribeck_velocity_rad_s) ** 2))
        )
        return (
            self.theta1 * (1.0 + a * math.sin(w * t)) * i
            + self.theta2 * v
            - friction
            - self.drag_per_rad * v * abs(v)
            + self.offset_rad_s2
        )


@dataclass
class JointRun:
    """What the synthetic loop recorded: per sample k, the angle and the current held before."""

    position_rad: np.ndarray  # measured (quantised)
    current_held_a: np.ndarray  # over the interval before sample k
    command_a: np.ndarray  # commanded at sample k (held over the interval after it)
    truth: Truth
    at_limit: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def record(self, name: str = 'synthetic') -> Record:
        """Return the run as one identification record."""
        return Record(DT_S, self.position_rad, self.current_held_a, self.at_limit, name)


def synthetic_joint(
    truth: Optional[Truth] = None,
    duration_s: float = 14.0,
    reference=None,
    counts_per_rev: float = 2.0**16,
    current_limit_a: float = 20.0,
) -> JointRun:
    """Run the joint in the PD loop on ``reference`` (default: the excitation)."""
    truth = truth or Truth()
    reference = reference or ExcitationReference()
    n = int(round(duration_s / DT_S))
    kp, kd = LOOP_RAD_S**2, 2.0 * LOOP_DAMPING * LOOP_RAD_S
    resolution = 2.0 * math.pi / counts_per_rev if counts_per_rev else 0.0
    q = v = 0.0
    y_prev = 0.0
    measured, held, command = np.empty(n), np.empty(n), np.empty(n)
    current = 0.0
    h = DT_S / 4
    for k in range(n):
        t = k * DT_S
        if k:  # integrate [t_k-1, t_k) with the current held
            for s in range(4):
                ts = t - DT_S + s * h
                a1 = truth.acceleration(ts, v, current)
                v2 = v + 0.5 * h * a1
                a2 = truth.acceleration(ts + 0.5 * h, v2, current)
                v3 = v + 0.5 * h * a2
                a3 = truth.acceleration(ts + 0.5 * h, v3, current)
                v4 = v + h * a3
                a4 = truth.acceleration(ts + h, v4, current)
                q += h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
                v += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        held[k] = current
        y = round(q / resolution) * resolution if resolution else q
        measured[k] = y
        r = reference.sample(t)
        speed = (y - y_prev) / DT_S if k else 0.0
        y_prev = y
        wanted = (
            r.acceleration_rad_s2 + kp * (r.position_rad - y) + kd * (r.velocity_rad_s - speed)
        )
        current = max(-current_limit_a, min(current_limit_a, wanted / LOOP_THETA1))
        command[k] = current
    at_limit = np.abs(held) >= current_limit_a
    return JointRun(measured, held, command, truth, at_limit)
