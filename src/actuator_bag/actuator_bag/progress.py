# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Progress of long operations on stderr, through tqdm (one library for every progress display)."""

from __future__ import annotations

import sys
from typing import IO, Optional

from tqdm import tqdm


class Progress:
    """``<label>: NN % (done/total unit, elapsed)`` on stderr.

    First after ``min_interval_s``, then at most that often, and once at the end, so a failing
    operation prints its one error line and nothing else.
    """

    def __init__(
        self,
        label: str,
        total: float,
        *,
        unit: str = '',
        min_interval_s: float = 0.5,
        stream: Optional[IO[str]] = None,
        enabled: bool = True,
    ) -> None:
        """Report for ``total`` units of work.

        Nothing is printed when total <= 0 or not enabled.
        """
        self.total = float(total)
        self.done = 0.0
        self.bar = tqdm(
            total=self.total,
            desc=label,
            unit=unit,
            file=stream if stream is not None else sys.stderr,
            disable=not (enabled and self.total > 0),
            mininterval=min_interval_s,
            delay=min_interval_s,
            dynamic_ncols=False,
            bar_format='{desc}: {percentage:3.0f} % ({n:.0f}/{total:.0f} {unit}, {elapsed})',
        )

    def update(self, done: float) -> None:
        """Report that ``done`` units are finished; the display closes at the total."""
        done = min(float(done), self.total)
        if done > self.done:
            self.bar.update(done - self.done)
            self.done = done
        if self.done >= self.total and not self.bar.disable:
            # The final line, also when the work took less than the display delay, ended by a
            # newline so that whatever is printed next starts a line of its own.
            meter = self.bar.format_dict
            shown = meter['elapsed'] >= self.bar.delay  # tqdm drew a line already: overwrite it
            self.bar.disable = True
            self.bar.fp.write(('\r' if shown else '') + self.bar.format_meter(**meter) + '\n')
            self.bar.fp.flush()
