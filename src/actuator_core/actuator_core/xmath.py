# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Elementary functions for a float or a numpy array: ``math`` on scalars, numpy on arrays.

The model and control laws are written once and run both per sample in the nodes (scalars,
where numpy's per-call overhead would cost about ten times the arithmetic) and vectorised
over many scenarios (arrays). Scalars take exactly the same path in the nodes and in the
offline loop, so the two agree to the bit.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

_ndarray = np.ndarray

#: A float, or a numpy array of floats (one per run of a batch): what these functions, the model
#: and the laws compute on. Any to a type checker: the two are used with the same operators.
FloatOrArray = Any


def exp(x):
    """e**x."""
    return np.exp(x) if isinstance(x, _ndarray) else math.exp(x)


def log(x):
    """Natural logarithm."""
    return np.log(x) if isinstance(x, _ndarray) else math.log(x)


def sin(x):
    """Sine."""
    return np.sin(x) if isinstance(x, _ndarray) else math.sin(x)


def cos(x):
    """Cosine."""
    return np.cos(x) if isinstance(x, _ndarray) else math.cos(x)


def tanh(x):
    """Hyperbolic tangent."""
    return np.tanh(x) if isinstance(x, _ndarray) else math.tanh(x)


def sign(x):
    """-1, 0 or 1 (sign(0) = 0)."""
    if isinstance(x, _ndarray):
        return np.sign(x)
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0 * x)


def fabs(x):
    """Absolute value."""
    return np.abs(x) if isinstance(x, _ndarray) else abs(x)


def isfinite(x):
    """Return True where x is neither NaN nor infinite."""
    return np.isfinite(x) if isinstance(x, _ndarray) else math.isfinite(x)


def where(condition, a, b):
    """Return a where condition holds, else b (both are evaluated)."""
    if isinstance(condition, _ndarray) or isinstance(a, _ndarray) or isinstance(b, _ndarray):
        return np.where(condition, a, b)
    return a if condition else b


def clip(x, low, high):
    """Return x limited to [low, high]."""
    if isinstance(x, _ndarray):
        return np.clip(x, low, high)
    return low if x < low else (high if x > high else x)


def all_true(x) -> bool:
    """``x`` (a bool or a bool array) is true everywhere."""
    return bool(np.all(x)) if isinstance(x, _ndarray) else bool(x)


def any_true(x) -> bool:
    """``x`` (a bool or a bool array) is true somewhere."""
    return bool(np.any(x)) if isinstance(x, _ndarray) else bool(x)


def logical_not(x):
    """Elementwise not of a boolean (``~`` is wrong on a Python bool)."""
    return np.logical_not(x) if isinstance(x, _ndarray) else not x
