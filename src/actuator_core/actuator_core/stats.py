# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Summaries of per-sample figures, one way everywhere: percentiles and missed samples."""

from __future__ import annotations

from typing import Optional

import numpy as np


def percentiles(values, prefix: str, mean: bool = False) -> dict[str, Optional[float]]:
    """{prefix_p50, prefix_p99, prefix_max (, prefix_mean)} of ``values``.

    None for an empty array.
    """
    v = np.asarray(values, dtype=float)
    keys = ('p50', 'p99', 'max') + (('mean',) if mean else ())
    if v.size == 0:
        return {f'{prefix}_{k}': None for k in keys}
    out: dict[str, Optional[float]] = {
        f'{prefix}_p50': float(np.percentile(v, 50)),
        f'{prefix}_p99': float(np.percentile(v, 99)),
        f'{prefix}_max': float(v.max()),
    }
    if mean:
        out[f'{prefix}_mean'] = float(v.mean())
    return out


def missed_samples(stamp_ns, period_ns: int) -> int:
    """Count the samples never answered.

    The sum over gaps between consecutive stamps of (floor(gap / period) - 1): a gap short of
    a whole number of periods (jitter) rounds down, so 1.9 periods count as none missed.
    """
    gaps = np.diff(np.asarray(stamp_ns, dtype=np.int64)) // period_ns - 1
    return int(gaps[gaps > 0].sum()) if gaps.size else 0
