# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The bags BagWriter makes are the rosbag2 (Jazzy, v9) + MCAP layout; rosbags reads them back."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import mcap.reader as mcap_reader  # noqa: E402 - pinned: a broken install fails, never skips
import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader

from actuator_bag.bag_format import (
    BagWriter,
    QosProfile,
    TopicSpec,
    mcap_name,
    qos_from_yaml,
    topic_spec,
)
from actuator_bag.errors import BagWriteError, DefinitionError
from actuator_bag.msgdefs import DefinitionSource, msg_dependencies, normalize_msgtype
from bag_helpers import (
    SOURCE,
    TOPICS,
    add_command_topic,
    command_cdr,
)

V9_TOP_KEYS = {
    'version',
    'storage_identifier',
    'duration',
    'starting_time',
    'message_count',
    'topics_with_message_count',
    'compression_format',
    'compression_mode',
    'relative_file_paths',
    'files',
    'custom_data',
    'ros_distro',
}
QOS_KEYS = {
    'history',
    'depth',
    'reliability',
    'durability',
    'deadline',
    'lifespan',
    'liveliness',
    'liveliness_lease_duration',
    'avoid_ros_namespace_conventions',
}


@pytest.mark.slow
def test_layout_and_metadata_v9(run_bag) -> None:
    """Folder holds metadata.yaml and <name>_0.mcap.

    Every version-gated v9 key is present and typed.
    """
    path, run = run_bag
    assert sorted(p.name for p in path.iterdir()) == ['case_0.mcap', 'metadata.yaml']
    info = yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert set(info) == V9_TOP_KEYS
    assert info['version'] == 9
    assert info['storage_identifier'] == 'mcap'
    assert info['ros_distro'] == 'jazzy'
    assert info['relative_file_paths'] == ['case_0.mcap']
    assert info['compression_format'] == '' and info['compression_mode'] == ''
    assert info['message_count'] == sum(run.counts.values())
    assert info['files'][0]['message_count'] == info['message_count']
    assert isinstance(info['custom_data'], dict)
    seen = {}
    for entry in info['topics_with_message_count']:
        meta = entry['topic_metadata']
        assert set(meta) == {
            'name',
            'type',
            'serialization_format',
            'offered_qos_profiles',
            'type_description_hash',
        }
        assert meta['serialization_format'] == 'cdr'
        assert isinstance(meta['offered_qos_profiles'], list)
        assert set(meta['offered_qos_profiles'][0]) == QOS_KEYS
        assert meta['type_description_hash'] == SOURCE.type_hash(meta['type'])
        seen[meta['name']] = entry['message_count']
    assert seen == run.counts


def test_mcap_records_match_rosbag2(run_bag) -> None:
    """The MCAP records are those rosbag2 writes.

    Profile ros2, ros2msg schemas with dependencies, cdr channels with QoS + hash, rosbag2 record,
    zstd chunks.
    """
    path, _ = run_bag
    info = yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    topics = {
        e['topic_metadata']['name']: e['topic_metadata'] for e in info['topics_with_message_count']
    }
    with open(path / mcap_name(path), 'rb') as bio:
        reader = mcap_reader.make_reader(bio)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        schemas = summary.schemas
        for channel in summary.channels.values():
            schema = schemas[channel.schema_id]
            meta = topics[channel.topic]
            assert channel.message_encoding == 'cdr'
            assert schema.encoding == 'ros2msg'
            assert schema.name == meta['type']
            text = schema.data.decode()
            assert text == SOURCE.full_text(meta['type'])
            assert '\n' + '=' * 80 + '\nMSG: std_msgs/Header\n' in text
            assert 'MSG: builtin_interfaces/Time\n' in text
            assert channel.metadata['topic_type_hash'] == meta['type_description_hash']
            qos = yaml.safe_load(channel.metadata['offered_qos_profiles'])
            assert qos == meta['offered_qos_profiles']
        assert summary.chunk_indexes and all(
            c.compression == 'zstd' for c in summary.chunk_indexes
        )
        assert len(summary.chunk_indexes) > 1
        records = list(reader.iter_metadata())
    assert [r.name for r in records] == ['rosbag2']
    assert yaml.safe_load(records[0].metadata['serialized_metadata']) == info


def test_rosbags_reads_back_bytes_and_types(tmp_path: Path) -> None:
    """The rosbags Reader returns exactly the bytes written, in order.

    AnyReader checks hashes and decodes.
    """
    written = []
    path = tmp_path / 'bytes'
    with BagWriter(path, chunk_size=2048) as writer:
        handle = add_command_topic(writer, '/ns/current_command')
        for k in range(500):
            data = command_cdr(k, k * 0.01, safe_stop=k % 2 == 0, sec=3, frame_id='f')
            writer.write(handle, 1_000 + k, data)
            written.append((1_000 + k, data))
    with Reader(path) as reader:
        assert reader.message_count == 500
        got = [(ts, bytes(raw)) for _, ts, raw in reader.messages()]
    assert got == written
    with AnyReader([path]) as reader:
        last = None
        for conn, _, raw in reader.messages():
            last = reader.deserialize(raw, conn.msgtype)
    assert last.current_a == pytest.approx(4.99) and last.header.stamp.nanosec == 499


def test_foxglove_ros2_decoder_reads_messages(run_bag) -> None:
    """mcap-ros2-support decodes every message from the embedded schemas.

    It is what Foxglove-style tools use.
    """
    import mcap_ros2.decoder as decoder_mod

    path, run = run_bag
    counts: dict[str, int] = {}
    with open(path / mcap_name(path), 'rb') as bio:
        reader = mcap_reader.make_reader(bio, decoder_factories=[decoder_mod.DecoderFactory()])
        for _, channel, _, msg in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            assert msg.header.stamp.sec > 0
    assert counts == run.counts


def test_never_overwrites(tmp_path: Path) -> None:
    """An existing folder (even empty) is refused."""
    (tmp_path / 'taken').mkdir()
    with pytest.raises(BagWriteError, match='exists already'):
        BagWriter(tmp_path / 'taken')


def test_argument_validation(tmp_path: Path) -> None:
    """Bad arguments fail up front with explicit errors."""
    with pytest.raises(BagWriteError):
        BagWriter(tmp_path / 'x', chunk_size=10)
    with pytest.raises(BagWriteError):
        BagWriter(tmp_path / 'x', flush_interval_s=0)
    with pytest.raises(BagWriteError):
        QosProfile(reliability='sometimes')
    with pytest.raises(BagWriteError):
        TopicSpec(name='relative', msgtype='std_msgs/msg/Header', definition='', type_hash='')
    with pytest.raises(DefinitionError):
        normalize_msgtype('not a type')
    with pytest.raises(DefinitionError, match='no .msg definition'):
        SOURCE.full_text('nowhere_msgs/msg/Missing')
    writer = BagWriter(tmp_path / 'closed')
    with pytest.raises(BagWriteError, match='not open'):
        writer.write(0, 0, b'')


def test_flushes_chunks_while_recording(tmp_path: Path) -> None:
    """With a short flush interval, finished chunks reach the file before close.

    That is what makes kill -9 survivable.
    """
    path = tmp_path / 'live'
    writer = BagWriter(path, flush_interval_s=0.05)
    writer.open()
    handle = writer.add_topic(topic_spec('/joint_states', 'sensor_msgs/msg/JointState', SOURCE))
    mcap_file = path / mcap_name(path)
    header_only = mcap_file.stat().st_size
    writer.write(handle, 1, b'\x00\x01\x00\x00' + bytes(60))
    time.sleep(0.1)
    writer.write(handle, 2, b'\x00\x01\x00\x00' + bytes(60))
    assert mcap_file.stat().st_size > header_only + 100
    assert not (path / 'metadata.yaml').exists()
    writer.abort()


def test_qos_yaml_round_trip() -> None:
    """A channel's offered_qos_profiles string parses back to the same profiles."""
    from actuator_bag.bag_format import qos_to_yaml

    profiles = (
        QosProfile(reliability='best_effort', depth=1000),
        QosProfile(durability='transient_local'),
    )
    assert qos_from_yaml(qos_to_yaml(profiles)) == profiles
    assert qos_from_yaml('') == ()


def test_dependency_parsing() -> None:
    """Field types resolve to pkg/Type; primitives, arrays, bounds and comments are handled."""
    text = (
        'std_msgs/Header header  # c\nfloat64[] a\nstring<=5 s\nOther[3] o\nuint8 K=1\n# Foo bar\n'
    )
    assert msg_dependencies(text, 'pkg') == ['pkg/Other', 'std_msgs/Header']


def test_hash_matches_rosidl_when_installed() -> None:
    """Where actuator_msgs is built, our RIHS01 hashes equal rosidl's.

    Built means share/actuator_msgs/msg/*.json from rosidl is there.
    """
    source = DefinitionSource()
    files = [source.find_file(t) for _, t in TOPICS.values() if t.startswith('actuator_msgs/')]
    files = [f for f in files if f is not None and f.with_suffix('.json').is_file()]
    assert files, 'actuator_msgs is installed without its rosidl type description JSON files'
    for msg_file in files:
        doc = json.loads(msg_file.with_suffix('.json').read_text())
        msgtype = doc['type_description_msg']['type_description']['type_name']
        expected = {h['type_name']: h['hash_string'] for h in doc['type_hashes']}[msgtype]
        assert source.type_hash(msgtype) == expected, msgtype
    assert os.environ.get('AMENT_PREFIX_PATH')
