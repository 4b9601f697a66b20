# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""How late the loop answers a sample: the delay its command will reach the joint with.

The controller receives y(k) at ``received_ns`` on its own monotonic clock; the stamp is the
sample's instant on the joint's grid. Their difference, the transit, is a delivery time plus an
unknown constant offset between the two clocks (and, across hosts, a slow drift). Its floor (the
smallest transit seen, allowed to rise by ``FLOOR_RISE_PER_SAMPLE`` of a period per sample so
that a drifting offset is followed) stands for on-time delivery; a sample whose transit is n
periods above it is answered n samples late. The joint applies a command from its first cycle
after the command arrives: ``base_delay_samples`` later for an on-time answer (1 in real time; 0
in sim time and offline, where u(k) acts over [t_k, t_k+1)), so the delay is base + n.
Held by ``ControlSampleAssembly``, which lowers the law's feedback while the delay is at least
``limits.LATE_FEEDBACK_DELAY_SAMPLES`` (resolution 28).
"""

from __future__ import annotations

from typing import Optional

#: How fast the floor may rise, in periods per sample: 1e-5 follows a clock drift of up to 10 ppm.
#: It falls at once to a faster transit; after a restarted time base ``reset`` starts it over.
FLOOR_RISE_PER_SAMPLE = 1.0e-5


class AnswerDelay:
    """The delay [samples] with which the joint will apply the answer to each sample."""

    def __init__(self, period_ns: int, base_delay_samples: int = 0):
        """``base_delay_samples``: the delay of an answer sent at once (module docstring)."""
        self.period_ns = period_ns
        self.base_delay_samples = base_delay_samples
        self.rise_ns = FLOOR_RISE_PER_SAMPLE * period_ns
        self.floor_ns: Optional[float] = None

    def update(self, stamp_ns: int, received_ns: int) -> int:
        """Take one sample's receipt; return the delay its answer will have [samples]."""
        transit = received_ns - stamp_ns
        if self.floor_ns is None or transit < self.floor_ns + self.rise_ns:
            self.floor_ns = float(transit)
        else:
            self.floor_ns += self.rise_ns
        late = int((transit - self.floor_ns) / self.period_ns + 0.5)
        return self.base_delay_samples + late

    def reset(self) -> None:
        """Forget the floor (a restarted time base: the clocks' offset is new)."""
        self.floor_ns = None
