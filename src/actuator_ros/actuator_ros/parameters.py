# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""ROS parameters declared from specifications: description, unit, range; refusals as one line.

Policy (docs/concepts/architecture.md#parameters): every parameter is declared with a description;
a value of the wrong type, out of range, or a name no node declares (a typo in a parameter file or
on the command line) is refused with one line naming it and the nearest declared name, and the node
exits 2. ``allow_unknown_parameters:=true`` turns unknown names into a warning, for parameter files
shared by several nodes (``/**`` sections). Parameters are read at configure: ``ros2 param set`` is
accepted only while the node is unconfigured (cleanup first), so what ``ros2 param get`` says is
always what the node runs with.
"""

from __future__ import annotations

import difflib
import math
import os
from dataclasses import make_dataclass
from typing import Any, Iterable, Mapping, Sequence, overload

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.node import Node

from actuator_core.loop_params import shared
from actuator_core.params import build, iter_specs, range_text, validate

#: The one description of the ``timing_log`` parameter every node of the loop declares.
TIMING_LOG_DESCRIPTION = (
    "the node's per-sample timing log (.npz: stamps, arrival and send times) written when it stops"
)


class ParameterError(ValueError):
    """A parameter value was refused; the message names the parameter and what is valid."""


def _descriptor(
    name: str, meta: Mapping[str, Any], default: Any, read_only: bool = False
) -> ParameterDescriptor:
    """Descriptor with description, unit, valid range and, where finite, an enforced range."""
    text = meta['description']
    if meta.get('choices'):
        text += f'; {range_text(meta)}'
    elif not isinstance(default, (bool, str)):
        text += f' [{meta["unit"] or "-"}], valid {range_text(meta)}'
    descriptor = ParameterDescriptor(name=name, description=text, read_only=read_only)
    low, high = meta['low'], meta['high']
    if isinstance(default, (bool, str)):
        return descriptor
    if isinstance(default, int) and math.isfinite(low) and math.isfinite(high):
        descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    elif isinstance(default, float) and math.isfinite(low) and math.isfinite(high):
        descriptor.floating_point_range = [
            FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)
        ]
    return descriptor


def _declare(
    node: Node, name: str, default: Any, descriptor: ParameterDescriptor, valid: str
) -> Any:
    """declare_parameter (or read it if declared).

    With type and range refusals as one ParameterError line.
    """
    try:
        # Declared once at construction; read again at configure
        # (a ros2 param set may have changed it).
        value = (
            node.get_parameter(name)
            if node.has_parameter(name)
            else node.declare_parameter(name, default, descriptor)
        ).value
    except Exception as exc:  # InvalidParameterTypeException, InvalidParameterValueException
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ParameterError(
            f'parameter {name!r} refused: expected {type(default).__name__} {valid} '
            f'({descriptor.description}); {reason}'
        ) from None
    if type(value) is not type(default) and not (
        isinstance(default, float) and isinstance(value, int)
    ):
        raise ParameterError(
            f'parameter {name!r} = {value!r} refused: expected {type(default).__name__} {valid}'
        )
    return float(value) if isinstance(default, float) else value


def declare_shared(node: Node, name: str) -> Any:
    """Declare one of the loop's shared parameters (actuator_core.loop_params) by its name."""
    one = make_dataclass(
        'Shared', [(name, Any, shared(name))], namespace={'__post_init__': validate}
    )
    return getattr(declare_spec_parameters(node, one), name)


def declare_spec_parameters(
    node: Node,
    cls: type,
    prefix: str = '',
    exclude: Iterable[str] = (),
    read_only: bool = False,
    **fixed: Any,
) -> Any:
    """Declare every spec'd field of dataclass ``cls`` and build ``cls``.

    Each is declared as ``prefix + dotted name``. ``exclude`` names fields not declared (their
    value comes from ``fixed`` or the default); ``read_only`` for a node that reads its parameters
    once, at start-up (the CiA 402 driver).
    """
    values: dict[str, Any] = dict(fixed)
    skip = set(exclude)
    for name, f in iter_specs(cls):
        if name in skip:
            continue
        full = prefix + name
        values[name] = _declare(
            node,
            full,
            f.default,
            _descriptor(full, f.metadata, f.default, read_only),
            f'in {range_text(f.metadata)}',
        )
        if f.metadata.get('choices'):
            _check_choice(full, values[name], f.metadata['choices'])
    try:
        return build(cls, values)
    except (ValueError, TypeError) as exc:
        raise ParameterError(f'{prefix}{exc}') from None


def declare_choice(
    node: Node, name: str, default: str, choices: Sequence[str], description: str
) -> str:
    """Declare a string parameter limited to ``choices``."""
    value = _declare(
        node,
        name,
        default,
        ParameterDescriptor(name=name, description=f'{description}; one of {", ".join(choices)}'),
        f'one of {", ".join(choices)}',
    )
    _check_choice(name, value, choices)
    return value


def _check_choice(name: str, value: str, choices: Sequence[str]) -> None:
    """Refuse a value outside ``choices`` in one line, with the nearest choice."""
    if value not in choices:
        near = difflib.get_close_matches(str(value), choices, n=1)
        hint = f' (did you mean {near[0]!r}?)' if near else ''
        raise ParameterError(
            f'parameter {name!r} = {value!r} refused: must be one of {", ".join(choices)}{hint}'
        )


@overload
def declare_number(
    node: Node, name: str, default: int, low: float, high: float, unit: str, description: str
) -> int: ...


@overload
def declare_number(
    node: Node, name: str, default: float, low: float, high: float, unit: str, description: str
) -> float: ...


def declare_number(
    node: Node,
    name: str,
    default: float | int,
    low: float,
    high: float,
    unit: str,
    description: str,
) -> float | int:
    """Declare a number parameter (an int when ``default`` is) in [low, high]."""
    meta = {'description': description, 'unit': unit, 'low': low, 'high': high, 'low_open': False}
    value = _declare(
        node, name, default, _descriptor(name, meta, default), f'in {range_text(meta)}'
    )
    if not (math.isfinite(value) and low <= value <= high):
        raise ParameterError(
            f'parameter {name!r} = {value} refused: valid {range_text(meta)} ({description})'
        )
    return value


def declare_text(node: Node, name: str, default: str, description: str) -> str:
    """Declare a free string parameter (a joint name, a label)."""
    return _declare(
        node, name, default, ParameterDescriptor(name=name, description=description), '(a string)'
    )


def declare_text_list(
    node: Node, name: str, default: Sequence[str], description: str
) -> list[str]:
    """Declare a list-of-strings parameter.

    ``default`` must not be empty: rclpy takes the parameter's type from it.
    """
    value = _declare(
        node,
        name,
        list(default),
        ParameterDescriptor(name=name, description=description),
        '(a list of strings)',
    )
    return [str(v) for v in value]


def declare_flag(node: Node, name: str, default: bool, description: str) -> bool:
    """Declare a boolean parameter."""
    return _declare(
        node,
        name,
        default,
        ParameterDescriptor(name=name, description=description),
        '(true or false)',
    )


def declare_output_path(node: Node, name: str, description: str) -> str:
    """Declare a file path the node writes at shutdown ('' = none).

    Refuse one whose folder is not writable.
    """
    path = declare_text(node, name, '', f'{description}; empty: not written')
    if path:
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder) or not os.access(folder, os.W_OK):
            raise ParameterError(
                f'parameter {name!r} = {path!r} refused: folder {folder!r} does not exist or '
                'is not writable'
            )
    return path


def check_unknown_parameters(node: Node) -> list[str]:
    """Names given to this node (parameter file or ``-p``) that it never declared.

    Raises ParameterError naming the first and the nearest declared name, unless the node's
    ``allow_unknown_parameters`` is true; then returns them (the caller logs a warning).
    """
    declared = set(node._parameters)  # noqa: SLF001 - rclpy keeps declared parameters here
    given = set(getattr(node, '_parameter_overrides', {}))
    unknown = sorted(given - declared)
    if unknown and not node.get_parameter('allow_unknown_parameters').value:
        first = unknown[0]
        near = difflib.get_close_matches(first, sorted(declared), n=1, cutoff=0.6)
        hint = f'; did you mean {near[0]!r}?' if near else ''
        more = (
            f' (and {len(unknown) - 1} more: {", ".join(unknown[1:])})' if len(unknown) > 1 else ''
        )
        raise ParameterError(
            f'parameter {first!r} is not a parameter of {node.get_name()}{hint}{more} '
            '(set allow_unknown_parameters:=true for a file shared by several nodes)'
        )
    return unknown


def declare_common(node: Node) -> None:
    """Parameters every managed node has: allow_unknown_parameters, autostart."""
    declare_flag(
        node,
        'allow_unknown_parameters',
        False,
        'accept names this node does not declare (a /** section shared by several nodes) '
        'with a warning instead of refusing them',
    )
    declare_flag(
        node,
        'autostart',
        False,
        'configure and activate at start-up '
        '(without it: ros2 lifecycle set <node> configure, activate)',
    )


def only_while_unconfigured(node) -> None:
    """Refuse ``ros2 param set`` unless the node is unconfigured.

    Parameters are read at configure.
    """

    def check(params) -> SetParametersResult:
        if getattr(node, 'configured', False):
            names = ', '.join(p.name for p in params)
            return SetParametersResult(
                successful=False,
                reason=(
                    f'{names}: parameters are read at configure; '
                    'deactivate and clean up the node first '
                    '(ros2 lifecycle set <node> deactivate, cleanup), '
                    'set them, then configure again'
                ),
            )
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(check)
