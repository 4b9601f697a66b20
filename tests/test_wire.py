# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The wire codec against rclpy's own (de)serialisation, for every message the loop sends.

A message filled with distinct values in every field (``fill_message``), encoded here and read
by rclpy, must equal the original; rclpy's bytes decoded here must give the same leaves.
"""

from __future__ import annotations

import importlib
import math
import struct

import pytest

from actuator_ros.wire import ENCAPSULATION, Codec, WireError
from message_fill import fill_message, message_leaves

#: rclpy's serialisation is the reference: ROS, not the unit set (which runs without rclpy);
#: rclpy and the message classes are imported in the tests, so the module collects without it.
pytestmark = pytest.mark.ros
LOOP_TYPES = (
    'sensor_msgs/JointState',
    'actuator_msgs/CurrentCommand',
    'actuator_msgs/StateEstimate',
    'actuator_msgs/ControllerState',
    'actuator_msgs/PlantTruth',
    'rosgraph_msgs/Clock',
)


def message(type_name: str):
    """'pkg/Type' -> the generated class."""
    package, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


def serialize_message(msg) -> bytes:
    """Return rclpy's CDR bytes of ``msg``."""
    from rclpy.serialization import serialize_message as serialize

    return bytes(serialize(msg))


def deserialize_message(data: bytes, cls):
    """Return rclpy's reading of ``data`` as a ``cls``."""
    from rclpy.serialization import deserialize_message as deserialize

    return deserialize(data, cls)


def codec_values(codec: Codec, msg) -> dict:
    """``msg``'s fields as the codec takes them (a Time as integer nanoseconds)."""
    values = {}
    for path in codec.fields:
        value = msg
        for part in path.split('.'):
            value = getattr(value, part)
        if hasattr(value, 'nanosec'):
            value = value.sec * 1_000_000_000 + value.nanosec
        values[path] = value
    return values


def view_leaves(view, prefix: str = '') -> dict:
    """Return a view flattened like ``message_leaves``."""
    out = {}
    for name, value in zip(view._fields, view):
        path = f'{prefix}{name}'
        if hasattr(value, '_fields'):
            out.update(view_leaves(value, path + '.'))
        elif isinstance(value, tuple):
            out.update({f'{path}[{i}]': item for i, item in enumerate(value)})
            if not value:
                out[path] = []
        else:
            out[path] = value
    return out


@pytest.mark.parametrize('type_name', LOOP_TYPES)
@pytest.mark.parametrize('seed', (0, 1, 2))
def test_what_the_codec_encodes_rclpy_reads_back_field_for_field(type_name, seed) -> None:
    """Every field, strings and sequences of three included (fill_message's values)."""
    cls = message(type_name)
    msg = fill_message(cls(), seed)
    codec = Codec(cls)
    assert deserialize_message(codec.encode(codec_values(codec, msg)), cls) == msg


@pytest.mark.parametrize('type_name', LOOP_TYPES)
def test_what_rclpy_serializes_the_codec_reads_field_for_field(type_name) -> None:
    """The view's leaves are the message's, exactly."""
    cls = message(type_name)
    msg = fill_message(cls(), 3)
    view = Codec(cls).decode(bytes(serialize_message(msg)))
    assert view_leaves(view) == message_leaves(msg)


@pytest.mark.parametrize('frame_id', ['', 'a', 'ab', 'abc', 'abcd', 'abcde', 'abcdef', 'abcdefg'])
def test_alignment_holds_for_every_string_length_before_a_double(frame_id) -> None:
    """The float64 after the header lands on each residue mod 8 in turn: padding right in all."""
    CurrentCommand = message('actuator_msgs/CurrentCommand')
    msg = CurrentCommand(current_a=-3.5, safe_stop=True)
    msg.header.frame_id = frame_id
    msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 999_999_999
    codec = Codec(CurrentCommand)
    assert deserialize_message(codec.encode(codec_values(codec, msg)), CurrentCommand) == msg
    view = codec.decode(bytes(serialize_message(msg)))
    assert (view.current_a, view.safe_stop, view.header.frame_id) == (-3.5, True, frame_id)
    assert (view.header.stamp.sec, view.header.stamp.nanosec) == (7, 999_999_999)


def test_a_joint_state_of_several_joints_and_empty_sequences() -> None:
    """The joint node's shape (one name, no velocity), a driver's (three joints), none."""
    JointState = message('sensor_msgs/JointState')
    codec = Codec(JointState)
    for names, position, velocity, effort in (
        (('joint',), (0.25,), (), (1.5,)),
        (('a', 'bb', 'ccc'), (1.0, -2.0, math.pi), (0.5, 0.0, -0.5), (9.0, 8.0, 7.0)),
        ((), (), (), ()),
    ):
        msg = JointState(name=list(names), position=position, velocity=velocity, effort=effort)
        view = codec.decode(bytes(serialize_message(msg)))
        assert (view.name, view.position, view.velocity, view.effort) == (
            names,
            position,
            velocity,
            effort,
        )
        assert deserialize_message(codec.encode(codec_values(codec, msg)), JointState) == msg


def test_the_same_bytes_twice_are_decoded_once_and_other_bytes_anew() -> None:
    """Two readers of one message share its view; a new message never gets the old one."""
    CurrentCommand = message('actuator_msgs/CurrentCommand')
    codec = Codec(CurrentCommand)
    first = serialize_message(CurrentCommand(current_a=1.0))
    second = serialize_message(CurrentCommand(current_a=2.0))
    view = codec.decode(first)
    assert codec.decode(bytes(first)) is view
    assert codec.decode(second).current_a == 2.0
    assert codec.decode(first).current_a == 1.0


def test_malformed_bytes_are_refused_with_the_reason() -> None:
    """Truncated, an overlong string, an impossible sequence count: WireError, never a value."""
    JointState = message('sensor_msgs/JointState')
    codec = Codec(JointState)
    good = bytes(serialize_message(JointState(name=['joint'], position=[0.1])))
    with pytest.raises(WireError, match='malformed'):
        codec.decode(good[:30])
    too_long = bytearray(good)
    struct.pack_into('<I', too_long, 12, 10_000)  # the frame_id's length
    with pytest.raises(WireError, match='string of length 10000'):
        codec.decode(bytes(too_long))
    header = ENCAPSULATION + struct.pack('<iII', 1, 2, 1) + b'\x00\x00\x00\x00'
    huge = header + struct.pack('<I', 0) + struct.pack('<I', 2**31)  # no names, 2^31 positions
    with pytest.raises(WireError, match='overruns'):
        codec.decode(huge)


def test_another_encapsulation_goes_to_the_fallback_or_is_refused() -> None:
    """Big-endian CDR is not read here: the fallback gets the bytes; without one, WireError."""
    CurrentCommand = message('actuator_msgs/CurrentCommand')
    big_endian = b'\x00\x00\x00\x00' + bytes(25)
    taken = []
    assert (
        Codec(CurrentCommand, fallback=lambda d: taken.append(d) or 'typed').decode(big_endian)
        == 'typed'
    )
    assert taken == [big_endian]
    with pytest.raises(WireError, match='not little-endian CDR'):
        Codec(CurrentCommand).decode(big_endian)


def test_a_field_type_the_codec_cannot_write_is_refused_when_it_is_built() -> None:
    """Not at the first message: at construction, naming the type."""

    class Wide:
        @staticmethod
        def get_fields_and_field_types():
            return {'text': 'wstring'}

    with pytest.raises(WireError, match="'wstring' is not supported"):
        Codec(Wide)


def test_encoding_without_a_field_fails_naming_it() -> None:
    """A publisher that forgot a field does not send a message with a default in it."""
    codec = Codec(message('actuator_msgs/CurrentCommand'))
    with pytest.raises(KeyError, match='safe_stop'):
        codec.encode({'header.stamp': 0, 'header.frame_id': '', 'current_a': 1.0})


def test_a_raw_subscription_hands_views_and_refuses_garbage_with_a_line(rclpy_context) -> None:
    """Via Fast DDS: a typed message arrives as a view; bytes that are none: logged, dropped."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from actuator_ros.wire_io import subscribe_views

    CurrentCommand = message('actuator_msgs/CurrentCommand')
    node = rclpy.create_node('wire_probe', context=rclpy_context)
    errors: list = []

    class Logger:
        def error(self, text, **_):
            errors.append(text)

    node.get_logger = Logger
    got: list = []
    try:
        subscribe_views(node, CurrentCommand, 'probe', got.append, 10)
        pub = node.create_publisher(CurrentCommand, 'probe', 10)
        executor = SingleThreadedExecutor(context=rclpy_context)
        executor.add_node(node)
        sent = CurrentCommand(current_a=2.5, safe_stop=True)
        sent.header.stamp.sec = 4
        pub.publish(ENCAPSULATION + b'\x01\x00')  # a header cut short
        pub.publish(sent)
        for _ in range(100):
            executor.spin_once(timeout_sec=0.05)
            if got and errors:
                break
    finally:
        node.destroy_node()
    assert [(v.header.stamp.sec, v.current_a, v.safe_stop) for v in got] == [(4, 2.5, True)]
    assert len(errors) == 1
    assert errors[0].startswith('probe: message refused, not a CurrentCommand')
