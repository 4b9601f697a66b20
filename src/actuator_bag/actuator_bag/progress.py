"""Progress lines on stderr for long operations: one line each time another step of the total is done."""

from __future__ import annotations

import sys
import time
from typing import IO, Optional


class Progress:
    """Prints ``<label>: NN % (done/total unit)`` on stderr every ``step_percent`` of ``total``."""

    def __init__(
        self,
        label: str,
        total: float,
        *,
        unit: str = '',
        step_percent: float = 10.0,
        stream: Optional[IO[str]] = None,
        enabled: bool = True,
    ) -> None:
        """Report for ``total`` units of work (nothing is printed when total <= 0 or not enabled)."""
        if not 0 < step_percent <= 100:
            raise ValueError(f'step_percent must be in (0, 100], not {step_percent}')
        self.label = label
        self.total = float(total)
        self.unit = unit
        self.step = step_percent
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled and self.total > 0
        self._next = step_percent
        self._start = time.monotonic()

    def update(self, done: float) -> None:
        """Report that ``done`` units are finished (prints when the next step is reached)."""
        if not self.enabled:
            return
        percent = 100.0 * min(done, self.total) / self.total
        if percent + 1e-9 < self._next:
            return
        while self._next <= percent + 1e-9:
            self._next += self.step
        unit = f' {self.unit}' if self.unit else ''
        elapsed = time.monotonic() - self._start
        print(
            f'{self.label}: {percent:3.0f} % ({done:.0f}/{self.total:.0f}{unit}, {elapsed:.1f} s)',
            file=self.stream,
            flush=True,
        )
