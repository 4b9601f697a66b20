# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""actuator_core.params: specs, ranges, the validation of settings and building them by name.

Each test kills mutants that survived ``make mutation`` (docs/mutation-report.md) or that no
test of the selection reached: a range end taken open for closed, a flag taken by its truth
value, a nested section not followed. The expected figures follow from the docstrings.
"""

import dataclasses
import math

import numpy as np
import pytest

from actuator_core import params


@dataclasses.dataclass(frozen=True)
class _Inner:
    """A nested section of spec'd fields."""

    gain: float = params.spec(2.0, 'a gain', '1/s', 0.0, 10.0, low_open=True)

    def __post_init__(self):
        """Validate as the project's settings do."""
        params.validate(self)


@dataclasses.dataclass(frozen=True)
class _Outer:
    """Spec'd fields, one plain field and a nested section (as the nodes' settings are)."""

    rate_hz: float = params.spec(100.0, 'a rate', 'Hz', 1.0, 1000.0)
    name: str = params.spec('joint', 'a name')
    plain: int = 3
    inner: _Inner = dataclasses.field(default_factory=_Inner)

    def __post_init__(self):
        """Validate as the project's settings do."""
        params.validate(self)


def test_spec_carries_its_description_unit_range_and_openness():
    """Every key of the metadata is the argument given, and the default is the field's."""
    f = params.spec(1.5, 'what it is', 'rad', -2.0, 3.0, low_open=True)
    assert f.default == 1.5
    assert dict(f.metadata) == {
        'description': 'what it is',
        'unit': 'rad',
        'low': -2.0,
        'high': 3.0,
        'low_open': True,
        'choices': (),
    }
    c = params.spec('a', 'one of two', choices=('a', 'b'))
    assert c.metadata['choices'] == ('a', 'b')
    assert params.range_text(c.metadata) == 'one of a, b'
    params.check_value('x', 'b', c.metadata)
    with pytest.raises(ValueError, match=r"^x = 'c' is not one of a, b$"):
        params.check_value('x', 'c', c.metadata)
    g = params.spec(0, 'unbounded')
    assert (g.metadata['unit'], g.metadata['low'], g.metadata['high']) == ('', -math.inf, math.inf)
    assert g.metadata['low_open'] is False


def test_range_text_says_open_or_closed_and_the_unit():
    """'(' for an open low end, '[' otherwise; ' unit' only when there is one."""
    meta = dict(params.spec(1.0, 'd', 'rad/s', 0.0, math.inf, low_open=True).metadata)
    assert params.range_text(meta) == '(0, inf] rad/s'
    meta = dict(params.spec(1.0, 'd', '', -1.5, 2.0).metadata)
    assert params.range_text(meta) == '[-1.5, 2]'


@pytest.mark.parametrize(
    'value, low_open, ok',
    [
        (0.0, False, True),  # the closed low end is in
        (0.0, True, False),  # the open low end is out
        (1.0, True, True),  # the high end is in
        (1.0 + 1e-12, False, False),
        (-1e-12, False, False),
        (math.nan, False, False),
        (math.inf, False, False),
        (np.array([0.5, 0.9]), True, True),
        (np.array([0.5, 1.5]), True, False),  # one element out is out
        (np.array([0.0, 0.5]), True, False),
    ],
)
def test_check_value_takes_the_range_ends_as_specified(value, low_open, ok):
    """[low, high] or (low, high]; NaN, inf and any element out of range refused."""
    meta = dict(params.spec(0.5, 'a fraction', '', 0.0, 1.0, low_open=low_open).metadata)
    if ok:
        params.check_value('x', value, meta)
        return
    with pytest.raises(ValueError) as info:
        params.check_value('x', value, meta)
    left = '(' if low_open else '['
    assert str(info.value) == f'x = {value} is outside its valid range {left}0, 1]: a fraction'


def test_check_value_leaves_strings_booleans_and_none_alone():
    """Non-numeric values are not range-checked (a name, a flag, an unset path)."""
    meta = dict(params.spec(0.5, 'd', '', 0.0, 1.0).metadata)
    for value in ('text', True, False, None):
        params.check_value('x', value, meta)


def test_validate_checks_every_spec_field_and_names_the_class():
    """The first bad field raises with 'Class.field'; a plain field is not checked."""
    assert _Outer(plain=-100).plain == -100
    with pytest.raises(ValueError, match=r'^_Outer\.rate_hz = 0\.5 is outside its valid range'):
        _Outer(rate_hz=0.5)
    with pytest.raises(ValueError, match=r'^_Outer\.rate_hz = 2000'):
        _Outer(rate_hz=2000.0)


@pytest.mark.parametrize('value', [None, '150', True, np.bool_(True)])
def test_validate_refuses_a_number_field_that_is_not_a_number(value):
    """None, a string or a flag in a number (a hand-edited file, a call) is refused by name."""
    with pytest.raises(ValueError) as info:
        _Outer(rate_hz=value)
    assert str(info.value) == f'_Outer.rate_hz = {value!r} is not a number: a rate'


def test_validate_takes_ints_floats_and_numeric_arrays_as_numbers():
    """An int where a float is declared (YAML's 100), numpy scalars and a batch's array."""
    assert _Outer(rate_hz=100).rate_hz == 100
    assert _Outer(rate_hz=np.float64(5.0)).rate_hz == 5.0
    assert list(_Outer(rate_hz=np.array([2.0, 3.0])).rate_hz) == [2.0, 3.0]
    assert _Outer(name='x').name == 'x'  # a text field stays text


@dataclasses.dataclass(frozen=True)
class _Flags:
    """A spec'd flag, as the plant model's with_* switches."""

    enabled: bool = params.spec(True, 'a switch')

    def __post_init__(self):
        """Validate as the project's settings do."""
        params.validate(self)


@pytest.mark.parametrize('value', [None, 'false', 0, 1.0])
def test_validate_refuses_a_flag_that_is_not_a_bool(value):
    """None, a string or a number in a flag is refused by name, not taken by its truth value."""
    with pytest.raises(ValueError) as info:
        _Flags(enabled=value)
    assert str(info.value) == f'_Flags.enabled = {value!r} is not true or false: a switch'


def test_validate_takes_a_python_or_numpy_bool_as_a_flag():
    """A flag from YAML or a ROS parameter (bool) or from a numpy table (numpy.bool_)."""
    assert _Flags(enabled=False).enabled is False
    assert not _Flags(enabled=np.bool_(False)).enabled


def test_iter_specs_recurses_into_nested_sections_with_dotted_names():
    """Spec'd fields in order, a nested section's with its prefix; plain fields left out."""
    names = [name for name, _ in params.iter_specs(_Outer)]
    assert names == ['rate_hz', 'name', 'inner.gain']
    assert [name for name, _ in params.iter_specs(_Outer, 'p.')] == [
        'p.rate_hz',
        'p.name',
        'p.inner.gain',
    ]
    fields = dict(params.iter_specs(_Outer))
    assert fields['inner.gain'].metadata['low_open'] is True


def test_build_fills_dotted_names_and_keeps_the_other_defaults():
    """A flat dict of dotted names builds the nested dataclass; a bad value still raises."""
    built = params.build(_Outer, {'rate_hz': 50.0, 'inner.gain': 4.0, 'unused': 1})
    assert built == _Outer(rate_hz=50.0, inner=_Inner(gain=4.0))
    assert params.build(_Outer, {}) == _Outer()
    assert params.build(_Inner, {'s.gain': 7.0}, 's.') == _Inner(gain=7.0)
    with pytest.raises(ValueError, match=r'^_Inner\.gain = 0'):
        params.build(_Outer, {'inner.gain': 0.0})


@dataclasses.dataclass(frozen=True)
class _Postponed:
    """Annotations as text, as in the settings modules (``from __future__ import annotations``).

    And a field whose factory is no dataclass.
    """

    rate_hz: 'float' = params.spec(100.0, 'a rate', 'Hz', 1.0, 1000.0)
    tags: 'list' = dataclasses.field(default_factory=list)
    inner: '_Inner' = dataclasses.field(default_factory=_Inner)


def test_iter_specs_and_build_follow_sections_whose_annotations_are_text():
    """A text annotation: the section is found by its factory; a list factory is no section."""
    assert isinstance(dataclasses.fields(_Postponed)[2].type, str)
    assert [name for name, _ in params.iter_specs(_Postponed)] == ['rate_hz', 'inner.gain']
    built = params.build(_Postponed, {'inner.gain': 5.0})
    assert built.inner == _Inner(gain=5.0) and built.tags == []


def test_check_value_judges_any_number_as_a_float():
    """A Fraction or a Decimal (numbers numpy keeps as objects) is checked by its value."""
    from decimal import Decimal
    from fractions import Fraction

    meta = dict(params.spec(0.5, 'a fraction', '', 0.0, 1.0).metadata)
    params.check_value('x', Fraction(1, 2), meta)
    params.check_value('x', Decimal('0.25'), meta)
    with pytest.raises(ValueError, match='outside its valid range'):
        params.check_value('x', Fraction(3, 2), meta)
