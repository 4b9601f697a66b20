# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""SampleLog.

Rows survive chunk boundaries, the cap counts instead of growing, files round-trip.
"""

import numpy as np

from actuator_core.sample_log import CHUNK_ROWS, SampleLog


def test_rows_across_chunks_and_cap(tmp_path):
    log = SampleLog(('a', 'b'), max_rows=2 * CHUNK_ROWS + 5)
    for i in range(3 * CHUNK_ROWS):
        log.append((i, -i))
    data = log.array()
    assert data.shape == (2 * CHUNK_ROWS + 5, 2)
    assert np.array_equal(data[:, 0], np.arange(2 * CHUNK_ROWS + 5))
    assert np.array_equal(data[:, 1], -np.arange(2 * CHUNK_ROWS + 5))
    assert log.dropped == 3 * CHUNK_ROWS - (2 * CHUNK_ROWS + 5)
    log.save(tmp_path / 'x.npz')
    loaded = np.load(tmp_path / 'x.npz')
    assert np.array_equal(loaded['a'], data[:, 0]) and np.array_equal(loaded['b'], data[:, 1])


def test_empty_log():
    log = SampleLog(('a', 'b', 'c'))
    assert log.array().shape == (0, 3) and log.rows == 0
