# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A per-sample log of integer rows that grows in chunks, so memory follows the run's length."""

from __future__ import annotations

from typing import Sequence

import numpy as np

#: Rows per chunk: 4096 rows of 4 int64 are 128 KiB.
CHUNK_ROWS = 4096


class SampleLog:
    """Append fixed-width int64 rows cheaply; ``array()`` joins them.

    Rows beyond ``max_rows`` are counted, not kept.
    """

    def __init__(self, columns: Sequence[str], max_rows: int = 3_600_000):
        """One column per name; at most ``max_rows`` rows (one hour at 1 kHz by default)."""
        self.columns = tuple(columns)
        self.max_rows = max_rows
        self._chunks: list[np.ndarray] = []
        self._fill = CHUNK_ROWS
        self.rows = 0
        self.dropped = 0

    def append(self, row: Sequence[int]) -> None:
        """Add one row (its length must match the columns)."""
        if self.rows >= self.max_rows:
            self.dropped += 1
            return
        if self._fill == CHUNK_ROWS:
            self._chunks.append(np.empty((CHUNK_ROWS, len(self.columns)), dtype=np.int64))
            self._fill = 0
        self._chunks[-1][self._fill] = row
        self._fill += 1
        self.rows += 1

    def array(self) -> np.ndarray:
        """All rows as one (rows, columns) array."""
        if not self._chunks:
            return np.empty((0, len(self.columns)), dtype=np.int64)
        return np.concatenate(self._chunks[:-1] + [self._chunks[-1][: self._fill]])

    def since(self, start: int) -> np.ndarray:
        """Rows ``start`` onwards (e.g. those of the last report), joining only their chunks."""
        first = max(start, 0) // CHUNK_ROWS
        if first >= len(self._chunks):
            return np.empty((0, len(self.columns)), dtype=np.int64)
        parts = self._chunks[first:-1] + [self._chunks[-1][: self._fill]]
        return np.concatenate(parts)[max(start, 0) - first * CHUNK_ROWS :]

    def save(self, path: str) -> None:
        """Write the columns as arrays of an .npz file."""
        data = self.array()
        # numpy's stub types **kwds as if they could hold its allow_pickle flag
        np.savez(path, **{name: data[:, i] for i, name in enumerate(self.columns)})  # type: ignore[arg-type]
