# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Messages for tests: every field filled with distinct values, and read back as flat leaves.

``fill_message`` gives each field of a generated message a value of its type that no other field
of it has (strings and sequences of three included); ``message_leaves`` flattens a message to
``{'field.sub[i]': value}`` for comparison (``leaves_equal``); ``interface_types`` lists the
interfaces a package registered in the ament index.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

_INT_RANGES = {
    'int8': (-(2**7), 2**7 - 1),
    'uint8': (0, 2**8 - 1),
    'int16': (-(2**15), 2**15 - 1),
    'uint16': (0, 2**16 - 1),
    'int32': (-(2**31), 2**31 - 1),
    'uint32': (0, 2**32 - 1),
    'int64': (-(2**63), 2**63 - 1),
    'uint64': (0, 2**64 - 1),
    'octet': (0, 255),
    'byte': (0, 255),
    'char': (0, 255),
}
_ARRAY_RE = re.compile(r'^(?P<base>.+?)\[(?P<size>\d+)\]$')
_SEQ_RE = re.compile(r'^sequence<(?P<base>.+?)(?:,\s*(?P<bound>\d+))?>$')
_STR_RE = re.compile(r'^(?P<kind>w?string)(?:<(?P<bound>\d+)>)?$')


class _Counter:
    def __init__(self, seed: int):
        self.k = seed

    def next(self) -> int:
        self.k += 1
        return self.k


def _scalar(type_name: str, counter: _Counter):
    k = counter.next()
    if type_name in ('double', 'float', 'float64', 'float32', 'long double'):
        return k + 0.25 + (k % 7) * 0.5  # exactly representable in float32 for small k
    if type_name in ('boolean', 'bool'):
        return True  # the default is False
    if type_name in _INT_RANGES:
        lo, hi = _INT_RANGES[type_name]
        value = 1 + (k * 37) % min(hi, 250)
        if type_name in ('octet', 'byte'):
            return bytes([value])
        if type_name == 'char':
            return chr(value % 127 or 65)  # rclpy's char is a 1-character str
        if hi >= 2**63 - 1:
            value += 2**32 + 7  # 64-bit types: beyond 32 bits, to catch truncation
        return value
    m = _STR_RE.match(type_name)
    if m:
        text = f'v{k}-éx' if m.group('kind') == 'wstring' else f'v{k}-x'
        bound = m.group('bound')
        return text[: int(bound)] if bound else text
    raise ValueError(f'no test value for type {type_name!r}')


def fill_message(msg, seed: int = 0):
    """Set every field of ``msg`` (recursively) to a value that differs from its default.

    Driven by ``get_fields_and_field_types()``, so a field added to a .msg file later is
    covered without touching the tests. Values depend on ``seed`` and on the field order
    only, so two processes that fill the same type with the same seed agree exactly.
    Returns ``msg``.
    """
    _fill(msg, _Counter(seed * 1000))
    return msg


def _fill(msg, counter: _Counter) -> None:
    for field, type_name in msg.get_fields_and_field_types().items():
        current = getattr(msg, field)
        setattr(msg, field, _value_for(type_name, current, counter))


def _value_for(type_name: str, current, counter: _Counter):
    m = _ARRAY_RE.match(type_name)
    if m:
        size = int(m.group('size'))
        items = [
            _value_for(m.group('base'), _element_template(current, m.group('base')), counter)
            for _ in range(size)
        ]
        return items
    m = _SEQ_RE.match(type_name)
    if m:
        bound = m.group('bound')
        size = min(3, int(bound)) if bound else 3
        return [
            _value_for(m.group('base'), _element_template(current, m.group('base')), counter)
            for _ in range(size)
        ]
    if '/' in type_name:  # nested message: fill a fresh instance of the field's class
        nested = (
            type(current)()
            if current is not None and not isinstance(current, (list, tuple))
            else _message_class(type_name)()
        )
        _fill(nested, counter)
        return nested
    value = _scalar(type_name, counter)
    return value


def _element_template(current, base_type: str):
    if '/' in base_type:
        return _message_class(base_type)()
    return None


def _message_class(type_name: str):
    """'pkg/Type' or 'pkg/msg/Type' to the Python class."""
    import importlib

    parts = type_name.split('/')
    pkg, name = parts[0], parts[-1]
    return getattr(importlib.import_module(f'{pkg}.msg'), name)


def message_leaves(msg, prefix: str = '') -> dict:
    """Flatten a message into {'field.sub[2].x': plain value}.

    Numbers, bools, str, bytes as ints.
    """
    out = {}
    for field, type_name in msg.get_fields_and_field_types().items():
        _leaves(getattr(msg, field), f'{prefix}{field}', out)
    return out


def _leaves(value, path: str, out: dict) -> None:
    if hasattr(value, 'get_fields_and_field_types'):
        out.update(message_leaves(value, path + '.'))
        return
    if isinstance(value, (bytes, bytearray)):
        out[path] = list(value)
        return
    if isinstance(value, str):
        out[path] = value
        return
    try:
        items = list(value)  # lists, array.array, numpy arrays
    except TypeError:
        out[path] = value.item() if hasattr(value, 'item') else value
        return
    for i, item in enumerate(items):
        _leaves(item, f'{path}[{i}]', out)
    if not items:
        out[path] = []


def leaves_equal(a: dict, b: dict) -> 'list[str]':
    """Differences between two ``message_leaves`` dicts (empty when identical; NaN == NaN)."""
    diffs = []
    for key in sorted(set(a) | set(b)):
        if key not in a or key not in b:
            diffs.append(f'{key}: only in {"first" if key in a else "second"}')
            continue
        x, y = a[key], b[key]
        same = x == y or (
            isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y)
        )
        if not same:
            diffs.append(f'{key}: {x!r} != {y!r}')
    return diffs


def interface_types(package: str, kind: str = 'msg') -> 'list[str]':
    """Names of the ``kind`` interfaces a package registered in the ament index."""
    from ament_index_python.resources import get_resource

    content, _ = get_resource('rosidl_interfaces', package)
    names = set()
    for line in content.splitlines():
        path = line.split(';')[0].strip()
        if path.startswith(f'{kind}/') and (path.endswith(f'.{kind}') or path.endswith('.idl')):
            names.add(Path(path).stem)
    return sorted(names)
