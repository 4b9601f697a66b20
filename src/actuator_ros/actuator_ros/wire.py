# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The loop's messages on the wire: CDR bytes to read-only views and values to CDR bytes.

rclpy builds a Python message object for every message it takes (a default one first, then its
fields; a Header and a Time each twice) and converts every field of a message it publishes through
the generated setters. On the loop's hot path that is most of a hop's Python cost: in one process,
publish + take + callback measured 18-20 us per CurrentCommand or JointState and 28 us per
ControllerState typed, 7.3-7.7 us raw (``raw=True``: the serialized bytes), 2026-12-05. So the
loop's nodes take and publish serialized messages and use this codec in between.

The layout comes from the generated message class (``get_fields_and_field_types``, i.e. the .msg
file), never from a copy of it here. Encoding: plain CDR, little endian (XCDR1, the encapsulation
Fast DDS gives ROS 2 types): every primitive aligned to its size counted from the payload's
start, a string as uint32 length with its NUL then the bytes, a sequence as uint32 count then
the elements. A ``Time`` field is one integer of nanoseconds on this side. Bytes this codec does
not read (another encapsulation, a malformed message) go to a fallback (rclpy's own
deserialisation in the nodes) or raise ``WireError`` with the reason.

A decoded message is a tree of named tuples with the message's field names (``msg.header.stamp.
sec``, ``msg.position``), so a callback reads a view and a generated message alike.
"""

from __future__ import annotations

import importlib
import struct
from collections import namedtuple
from typing import Any, Callable, Mapping, NamedTuple, cast

#: CDR, little endian: the 4-byte encapsulation header this codec writes and reads.
ENCAPSULATION = b'\x00\x01\x00\x00'
#: The payload starts after the encapsulation header; alignment counts from there.
PAYLOAD_OFFSET = 4
#: IDL primitive -> struct code (size = alignment). char and octet, which rclpy gives as str and
#: bytes, are not here: no message of the loop has them.
PRIMITIVES = {
    'boolean': '?',
    'uint8': 'B',
    'int8': 'b',
    'uint16': 'H',
    'int16': 'h',
    'uint32': 'I',
    'int32': 'i',
    'uint64': 'Q',
    'int64': 'q',
    'float': 'f',
    'double': 'd',
}
TIME_TYPE = 'builtin_interfaces/Time'
NS_PER_S = 1_000_000_000
_UINT32 = struct.Struct('<I')


class WireError(ValueError):
    """Bytes that are not a message of the expected type (the reason in one line)."""


def _message_class(type_name: str):
    """'std_msgs/Header' -> the generated class std_msgs.msg.Header."""
    package, _, name = type_name.partition('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


class _Leaf:
    """One field on the wire: a primitive, a string, a Time (as ns), or a sequence of either."""

    __slots__ = ('code', 'string', 'sequence', 'time', 'width')

    def __init__(self, type_name: str):
        self.sequence = type_name.startswith('sequence<')
        element = type_name[len('sequence<') : -1] if self.sequence else type_name
        self.time = element == TIME_TYPE and not self.sequence
        self.string = element == 'string'
        self.code = PRIMITIVES.get(element, '')
        # Alignment and size of one element (a Time and a string's length align to 4).
        self.width = struct.calcsize(self.code) if self.code else 4
        if not (self.time or self.string or self.code):
            raise WireError(f'field type {type_name!r} is not supported by the wire codec')


def _walk(cls, prefix: str, leaves: list, shape: list) -> None:
    """Flatten ``cls``'s fields into ``leaves`` (path, _Leaf); ``shape`` mirrors the tree."""
    for name, type_name in cls.get_fields_and_field_types().items():
        path = f'{prefix}{name}'
        if type_name == TIME_TYPE or type_name.startswith('sequence<') or '/' not in type_name:
            leaves.append((path, _Leaf(type_name)))
            shape.append(None)
            continue
        nested = _message_class(type_name)
        inner: list = []
        shape.append((nested, inner))
        _walk(nested, f'{path}.', leaves, inner)


class Codec:
    """CDR (de)serialisation of one message type, compiled from its generated class."""

    def __init__(self, cls, fallback: Callable[[bytes], Any] | None = None):
        """``fallback(data)`` reads what this codec does not (rclpy's deserialize_message)."""
        self.cls = cls
        self.fallback = fallback
        leaves: list = []
        shape: list = []
        _walk(cls, '', leaves, shape)
        self.fields = tuple(path for path, _ in leaves)  # the keys of ``encode``
        self._leaves = tuple(leaf for _, leaf in leaves)
        self._build = self._builder(self._view_type(cls, shape))
        self._runs = _runs(self._leaves)
        self._structs: dict = {}
        self._last: tuple = (None, None)  # (bytes, view) of the newest decoded message

    # --- views -----------------------------------------------------------------------------
    def _view_type(self, cls, shape: list):
        """Return the named-tuple class of ``cls`` (nested ones for nested messages)."""
        names = list(cls.get_fields_and_field_types())
        # a class made at run time from the message's fields: Any to mypy
        view: Any = cast(Any, namedtuple(cls.__name__ + 'View', names))
        view.inner = [None if s is None else self._view_type(*s) for s in shape]
        return view

    def _builder(self, view) -> Callable[[list, int], tuple]:
        """Return a function that makes ``view`` from flat values at an index: (view, next)."""
        make, size = view._make, len(view.inner)
        if all(inner is None for inner in view.inner):  # leaves only: one slice
            return lambda values, index: (make(values[index : index + size]), index + size)
        parts = [None if inner is None else self._builder(inner) for inner in view.inner]

        def build(values: list, index: int) -> tuple:
            args = []
            for part in parts:
                if part is None:
                    args.append(values[index])
                    index += 1
                else:
                    value, index = part(values, index)
                    args.append(value)
            return make(args), index

        return build

    # --- decoding ----------------------------------------------------------------------------
    def decode(self, data: bytes):
        """Return the message in ``data`` as a view (Time fields as Time views: sec, nanosec).

        The same bytes twice in a row (two readers of one message in one process: the ESO and
        the controller each take the joint's sample) give the same view, decoded once.
        """
        last = self._last  # one read: another thread may replace it
        if data == last[0]:
            return last[1]
        if bytes(data[:2]) != ENCAPSULATION[:2]:
            if self.fallback is not None:
                return self.fallback(data)
            raise WireError(
                f'{self.cls.__name__}: encapsulation {bytes(data[:2]).hex()} is not little-'
                'endian CDR'
            )
        try:
            values = self._read(data)
        except (struct.error, UnicodeDecodeError, IndexError) as exc:
            raise WireError(f'{self.cls.__name__}: malformed ({exc})') from None
        view = self._build(values, 0)[0]
        self._last = (bytes(data), view)
        return view

    def _read(self, data: bytes) -> list:
        """Return the flat field values of ``data`` (a Time as a TimeView)."""
        values: list = []
        offset = PAYLOAD_OFFSET
        size = len(data)
        for run in self._runs:
            if run.leaves:  # primitives and times: one struct per start alignment
                unpacker = run.unpacker((offset - PAYLOAD_OFFSET) % 8)
                read = unpacker.unpack_from(data, offset)
                offset += unpacker.size
                if run.times:
                    read = list(read)
                    for i in run.times:  # from the last: the indices before stay valid
                        read[i : i + 2] = [_TIME_VIEW(read[i], read[i + 1])]
                values.extend(read)
            elif run.leaf.sequence:
                offset += -(offset - PAYLOAD_OFFSET) % 4
                (count,) = _UINT32.unpack_from(data, offset)
                offset += 4
                if run.leaf.string:
                    items = []
                    for _ in range(count):
                        text, offset = _read_string(data, offset, size)
                        items.append(text)
                    values.append(tuple(items))
                else:
                    width = run.leaf.width
                    if count and count * width > size - offset:
                        raise WireError(f'{self.cls.__name__}: a sequence of {count} overruns')
                    if count:
                        offset += -(offset - PAYLOAD_OFFSET) % width
                    values.append(struct.unpack_from(f'<{count}{run.leaf.code}', data, offset))
                    offset += count * width
            else:
                text, offset = _read_string(data, offset, size)
                values.append(text)
        return values

    # --- encoding ----------------------------------------------------------------------------
    def encode(self, values: Mapping[str, Any]) -> bytes:
        """Return the CDR bytes of the message with these ``values`` (``fields``; Time: ns)."""
        flat: list = []
        key: list = []  # string lengths and sequence counts: they fix the layout
        for path, leaf in zip(self.fields, self._leaves):
            value = values[path]
            if leaf.time:
                ns = int(value)
                flat += (ns // NS_PER_S, ns % NS_PER_S)
            elif leaf.sequence:
                items = tuple(value)
                key.append(len(items))
                flat.append(len(items))
                if leaf.string:
                    for text in items:
                        raw = text.encode() + b'\x00'
                        key.append(len(raw))
                        flat += (len(raw), raw)
                else:
                    flat += items
            elif leaf.string:
                raw = value.encode() + b'\x00'
                key.append(len(raw))
                flat += (len(raw), raw)
            else:
                flat.append(value)
        layout = tuple(key)
        packer = self._structs.get(layout)
        if packer is None:
            packer = self._structs[layout] = struct.Struct(self._format(layout))
        try:
            return ENCAPSULATION + packer.pack(*flat)
        except struct.error as exc:
            raise WireError(f'{self.cls.__name__}: cannot encode ({exc})') from None

    def _format(self, layout: tuple) -> str:
        """Return the payload's struct format for these string lengths and sequence counts."""
        parts = ['<']
        offset = 0
        sizes = iter(layout)

        def align(width: int) -> None:
            nonlocal offset
            pad = -offset % width
            if pad:
                parts.append(f'{pad}x')
            offset += pad

        def field(code: str, width: int, size: int) -> None:
            nonlocal offset
            align(width)
            parts.append(code)
            offset += size

        def text() -> None:
            length = next(sizes)
            field(f'I{length}s', 4, 4 + length)

        for leaf in self._leaves:
            width = leaf.width
            if leaf.time:
                field('iI', 4, 8)
            elif leaf.sequence:
                count = next(sizes)
                field('I', 4, 4)
                for _ in range(count):
                    if leaf.string:
                        text()
                    else:
                        field(leaf.code, width, width)
            elif leaf.string:
                text()
            else:
                field(leaf.code, width, width)
        return ''.join(parts)


class _Run:
    """Consecutive fixed-size fields (``leaves``) read by one struct, or one string or sequence."""

    __slots__ = ('leaf', 'leaves', 'times', '_unpackers')

    def __init__(self, leaf: _Leaf | None = None, leaves: list | None = None):
        self.leaf = leaf
        self.leaves = leaves or []
        self._unpackers: dict = {}
        # Where each Time's (sec, nanosec) pair starts in the unpacked tuple, the last first.
        starts, position = [], 0
        for item in self.leaves:
            if item.time:
                starts.append(position)
            position += 2 if item.time else 1
        self.times = starts[::-1]

    def unpacker(self, residue: int) -> struct.Struct:
        """Return the struct of these fields starting ``residue`` bytes past an 8-byte boundary."""
        unpacker = self._unpackers.get(residue)
        if unpacker is None:
            parts, offset = ['<'], residue
            for item in self.leaves:
                code = 'iI' if item.time else item.code
                pad = -offset % item.width
                parts.append(f'{pad}x{code}' if pad else code)
                offset += pad + (8 if item.time else item.width)
            unpacker = self._unpackers[residue] = struct.Struct(''.join(parts))
        return unpacker


def _runs(leaves: tuple) -> list:
    """Group fixed-size leaves between strings and sequences."""
    runs: list = []
    for leaf in leaves:
        if leaf.string or leaf.sequence:
            runs.append(_Run(leaf=leaf))
        elif runs and runs[-1].leaves:
            runs[-1] = _Run(leaves=runs[-1].leaves + [leaf])
        else:
            runs.append(_Run(leaves=[leaf]))
    return runs


def _read_string(data: bytes, offset: int, size: int) -> tuple[str, int]:
    """Return the CDR string at ``offset`` (aligned to 4 first) and the offset after it."""
    offset += -(offset - PAYLOAD_OFFSET) % 4
    (length,) = _UINT32.unpack_from(data, offset)
    end = offset + 4 + length
    if length < 1 or end > size or data[end - 1] != 0:
        raise WireError(f'a string of length {length} at byte {offset} is malformed')
    return bytes(data[offset + 4 : end - 1]).decode(), end


class TimeView(NamedTuple):
    """A decoded builtin_interfaces/Time."""

    sec: int
    nanosec: int


_TIME_VIEW = TimeView
