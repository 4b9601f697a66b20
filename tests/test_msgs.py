# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""actuator_msgs: every type is built, serialises losslessly and crosses between processes.

The types come from the ament index (what the build registered), the fields from each
type's get_fields_and_field_types(), so a new message or field is covered automatically.
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import pytest

import message_fill
import ros_helpers

#: Generated message code and rclpy's serialisation: ROS, not the unit set (which runs without
#: rclpy); imported in the tests, so the module collects without it.
pytestmark = pytest.mark.ros

PACKAGE = 'actuator_msgs'
MSG_DIR = ros_helpers.WORKSPACE / 'src' / PACKAGE / 'msg'
HERE = Path(__file__).resolve().parent


def _types():
    return message_fill.interface_types(PACKAGE, 'msg')


def _class(name):
    return getattr(importlib.import_module(f'{PACKAGE}.msg'), name)


def test_every_msg_file_is_built_and_indexed():
    in_source = sorted(p.stem for p in MSG_DIR.glob('*.msg'))
    assert in_source, f'no .msg files in {MSG_DIR}'
    assert _types() == in_source
    for name in in_source:
        assert _class(name)().get_fields_and_field_types(), f'{name} has no fields'


@pytest.mark.parametrize('name', _types())
def test_serialization_round_trip_keeps_every_field(name):
    from rclpy.serialization import deserialize_message, serialize_message

    cls = _class(name)
    default = message_fill.message_leaves(cls())
    msg = message_fill.fill_message(cls(), seed=3)
    filled = message_fill.message_leaves(msg)

    # The filler really changed every field (a field it cannot fill would hide a loss).
    unchanged = [k for k in default if k in filled and filled[k] == default[k]]
    assert not unchanged, f'fill_message left defaults in {unchanged}'

    data = serialize_message(msg)
    assert isinstance(data, bytes) and len(data) > 4
    back = deserialize_message(data, cls)
    assert message_fill.leaves_equal(filled, message_fill.message_leaves(back)) == []
    assert back == msg

    # And a second, different filling does not compare equal (the comparison has teeth).
    other = message_fill.fill_message(cls(), seed=4)
    assert deserialize_message(serialize_message(other), cls) != msg


def test_constants_survive_in_generated_code():
    # ControllerState declares its status codes as constants; the generated class carries them.
    state = _class('ControllerState')
    codes = {k: getattr(state, k) for k in dir(state) if k.startswith('STATUS_')}
    assert codes, 'ControllerState has no STATUS_* constants'
    assert len(set(codes.values())) == len(codes)
    assert codes['STATUS_OK'] == 0


def test_status_codes_are_the_core_status_enum():
    # One place says what each code means (actuator_core/status.py);
    # the message carries the same numbers.
    from actuator_core.status import Status

    state = _class('ControllerState')
    codes = {k[len('STATUS_') :]: getattr(state, k) for k in dir(state) if k.startswith('STATUS_')}
    assert codes == {s.name: int(s) for s in Status}


def test_every_type_crosses_between_two_processes(ros_env, tmp_path):
    names = _types()
    seed = 11
    expected = {
        name: message_fill.message_leaves(message_fill.fill_message(_class(name)(), seed + i))
        for i, name in enumerate(names)
    }
    script = HERE / 'msg_exchange.py'
    common = ['--package', PACKAGE, '--types', ','.join(names)]
    with ros_helpers.RosProcess.python(
        script,
        ['pub', *common, '--seed', str(seed)],
        env=ros_env,
        log_dir=tmp_path,
        name='publisher',
    ) as pub:
        pub.wait_for_output(r'^READY$', timeout=30)
        with ros_helpers.RosProcess.python(
            script,
            ['sub', *common, '--timeout', '30'],
            env=ros_env,
            log_dir=tmp_path,
            name='subscriber',
        ) as sub:
            rc = sub.wait(timeout=60)
        assert rc == 0, sub.describe()
        assert pub.running, pub.describe()
    # The publisher stopped on the first signal (SIGINT) and exited cleanly.
    assert pub.stopped_by == 'SIGINT', pub.describe()
    assert pub.returncode == 0, pub.describe()

    line = [ln for ln in sub.stdout.splitlines() if ln.startswith('RECEIVED ')][-1]
    received = json.loads(line[len('RECEIVED ') :])
    assert sorted(received) == names
    for name in names:
        assert message_fill.leaves_equal(expected[name], received[name]) == [], name
