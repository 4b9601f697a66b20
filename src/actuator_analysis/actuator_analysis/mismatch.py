# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""How far the observer's b0 = theta1n seems from the joint's theta1, read from any recorded run.

The row ``bag_analyze`` prints so that an ordinary run tells whether identification is worth
doing. From the measured angle and the current the joint held (the command of the sample before,
as controller/state records it), band-passed to ``BAND_HZ`` (zero phase, so a constant load and a
slow disturbance, which the controller's current compensates and which would otherwise pose as
a slope, drop out): q'' = theta1 i + theta2 q' - fc sign(q'), least squares over the whole run
after ``START_S`` and over each window of ``WINDOW_S``. The acceleration and velocity are the
differences of the angle low-passed as ``identify`` does. theta1n is the observer's own, read from
eso/estimate (input_current_gain = dt theta1n). A joint whose windows disagree drifts (the
paper's eq. (41)): one b0 cannot fit it, and the range says by how much.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
from scipy import signal

from .identify import FILTER_CUTOFF_HZ, lowpass

#: Band of the regression [Hz], where the window starts [s], window length [s].
BAND_HZ = (1.0, 10.0)
START_S = 1.0
WINDOW_S = 2.0
#: Beyond this relative distance the row says identification is worth doing.
WORTH_IDENTIFYING = 0.10


@dataclass(frozen=True)
class B0Mismatch:
    """theta1 as the run shows it, against the observer's theta1n."""

    theta1n: Optional[float]  # None without eso/estimate
    theta1_seen: float
    window_low: float
    window_high: float
    windows: int

    @property
    def relative(self) -> Optional[float]:
        """theta1_seen / theta1n - 1, or None without theta1n."""
        return None if not self.theta1n else self.theta1_seen / self.theta1n - 1.0

    def as_dict(self) -> dict:
        """Plain-dict form."""
        return {**self.__dict__, 'relative': self.relative}


def theta1_seen(
    position_rad: np.ndarray, current_held_a: np.ndarray, dt_s: float, usable: np.ndarray
) -> Optional[tuple[float, list[float]]]:
    """theta1 over the usable windows and per window; None when no window is usable.

    ``current_held_a[k]`` is the current held over the interval before sample k; ``usable``
    marks the samples where the law commanded the current (a window with any other is skipped).
    """
    n = len(position_rad)
    start, width = int(round(START_S / dt_s)), int(round(WINDOW_S / dt_s))
    if n < start + width + 2 or 2.0 * BAND_HZ[1] * dt_s >= 1.0:
        return None
    yf = lowpass(np.asarray(position_rad, dtype=float), dt_s, FILTER_CUTOFF_HZ)
    k = np.arange(1, n - 1)
    acc = (yf[k + 1] - 2.0 * yf[k] + yf[k - 1]) / (dt_s * dt_s)
    vel = (yf[k + 1] - yf[k - 1]) / (2.0 * dt_s)
    held = np.asarray(current_held_a, dtype=float)
    current = 0.5 * (held[k] + held[k + 1])  # at t_k: the intervals before and after it
    sos = signal.butter(2, BAND_HZ, btype='bandpass', fs=1.0 / dt_s, output='sos')
    x = np.column_stack([signal.sosfiltfilt(sos, c) for c in (current, vel, -np.sign(vel))])
    a = signal.sosfiltfilt(sos, acc)
    ok = np.asarray(usable, dtype=bool)[k]
    windows: list[np.ndarray] = []
    per_window: list[float] = []
    for s in range(start, len(a) - width + 1, width):
        if ok[s : s + width].all():
            windows.append(np.arange(s, s + width))
            per_window.append(
                float(np.linalg.lstsq(x[windows[-1]], a[windows[-1]], rcond=None)[0][0])
            )
    if not windows:
        return None
    rows = np.concatenate(windows)
    return float(np.linalg.lstsq(x[rows], a[rows], rcond=None)[0][0]), per_window


def b0_mismatch(
    position_rad: np.ndarray,
    current_held_a: np.ndarray,
    dt_s: float,
    usable: np.ndarray,
    theta1n: Optional[float],
) -> Optional[B0Mismatch]:
    """Return the row's figures; None when the run is too short or never controls a window."""
    seen = theta1_seen(position_rad, current_held_a, dt_s, usable)
    if seen is None:
        return None
    overall, windows = seen
    return B0Mismatch(theta1n, overall, min(windows), max(windows), len(windows))
