# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Parameter specifications: each dataclass field carries its unit, valid range and description.

One declaration serves three users: the dataclass validates itself on construction, the
ROS nodes declare their parameters (description and range) from it, and the docs list it.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Iterator, Mapping

import numpy as np


def spec(
    default: Any,
    description: str,
    unit: str = '',
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    choices: tuple = (),
) -> Any:
    """Return a dataclass field with a valid range (or choices) and a description.

    The range is [low, high], or (low, high] when ``low_open``; ``choices``: the values a text
    parameter may take.
    """
    return dataclasses.field(
        default=default,
        metadata={
            'description': description,
            'unit': unit,
            'low': low,
            'high': high,
            'low_open': low_open,
            'choices': tuple(choices),
        },
    )


def range_text(meta: Mapping[str, Any]) -> str:
    """Human-readable valid range of a spec'd field, e.g. '(0, inf] rad/s', or its choices."""
    if meta.get('choices'):
        return 'one of ' + ', '.join(meta['choices'])
    left = '(' if meta['low_open'] else '['
    unit = f' {meta["unit"]}' if meta['unit'] else ''
    return f'{left}{meta["low"]:g}, {meta["high"]:g}]{unit}'


def check_value(name: str, value: Any, meta: Mapping[str, Any]) -> None:
    """Raise ValueError naming ``name``.

    Its value and its valid range when ``value`` is outside it.
    """
    choices = meta.get('choices', ())
    if choices and value not in choices:
        raise ValueError(f'{name} = {value!r} is not one of {", ".join(choices)}')
    if isinstance(value, (bool, str)) or value is None:
        return
    v = np.asarray(value, dtype=float)
    low, high = meta['low'], meta['high']
    ok = (
        np.all(np.isfinite(v))
        and np.all(v <= high)
        and (np.all(v > low) if meta['low_open'] else np.all(v >= low))
    )
    if not ok:
        raise ValueError(
            f'{name} = {value} is outside its valid range {range_text(meta)}: '
            f'{meta["description"]}'
        )


def validate(obj: Any) -> None:
    """Check every spec'd field of a dataclass instance; raise ValueError on the first bad one.

    A number against its range, and a number it must be (a string or None in a file or a call
    would otherwise pass unchecked); a flag (a field whose default is a bool) must be a bool, as
    a string such as 'false' or None would otherwise pass for one by its truth value.
    """
    for f in dataclasses.fields(obj):
        if 'low' in f.metadata:
            name, value = f'{type(obj).__name__}.{f.name}', getattr(obj, f.name)
            if isinstance(f.default, bool) and not isinstance(value, (bool, np.bool_)):
                raise ValueError(
                    f'{name} = {value!r} is not true or false: {f.metadata["description"]}'
                )
            if _is_number(f.default) and not _is_number(value):
                raise ValueError(
                    f'{name} = {value!r} is not a number: {f.metadata["description"]}'
                )
            check_value(name, value, f.metadata)


def _is_number(value: Any) -> bool:
    """Return whether ``value`` is a real number or an array of them (a bool is not one)."""
    if isinstance(value, (bool, np.bool_, str)) or value is None:
        return False
    return np.asarray(value).dtype.kind in 'iuf'


def require_below(obj: Any, low: str, high: str) -> None:
    """Raise ValueError unless field ``low`` of ``obj`` is below field ``high`` (a window)."""
    if not getattr(obj, low) < getattr(obj, high):
        raise ValueError(
            f'{low} = {getattr(obj, low)} must be below {high} = {getattr(obj, high)}'
        )


def _section(f: dataclasses.Field) -> Any:
    """Return the dataclass a field nests (its default factory is one), or None for a value."""
    factory = f.default_factory
    return (
        factory
        if factory is not dataclasses.MISSING and dataclasses.is_dataclass(factory)
        else None
    )


def iter_specs(cls: type, prefix: str = '') -> Iterator[tuple[str, dataclasses.Field]]:
    """Yield (dotted name, field) of every spec'd field of ``cls``.

    Nested dataclasses (a field whose default factory is one) are recursed into.
    """
    for f in dataclasses.fields(cls):
        section = _section(f)
        if section is not None:
            yield from iter_specs(section, f'{prefix}{f.name}.')
        elif 'low' in f.metadata:
            yield f'{prefix}{f.name}', f


def build(cls: type, values: dict[str, Any], prefix: str = '') -> Any:
    """Construct ``cls`` from a flat dict of dotted names (missing names keep their defaults)."""
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        section = _section(f)
        if section is not None:
            kwargs[f.name] = build(section, values, f'{prefix}{f.name}.')
        elif f'{prefix}{f.name}' in values:
            kwargs[f.name] = values[f'{prefix}{f.name}']
    return cls(**kwargs)
