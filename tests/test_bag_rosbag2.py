# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Bags as ``ros2 bag record`` writes them, read by the analysis, the player and the repair.

The bags are made with rosbags' writer in rosbag2's conventions: MCAP (uncompressed, and zstd
file compression) or sqlite3 storage, one or two files (a split bag), log times on the
recorder's wall clock, and the extra topics of ``ros2 bag record -a``: /rosout,
/parameter_events, /diagnostics, and /events/write_split, a topic with no message whose type
(rosbag2_interfaces/msg/WriteSplitEvent) is not installed and has no definition in the bag.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

from actuator_analysis.analyze import analyze_run, load_run
from actuator_analysis.analyze_table import format_table
from actuator_bag.repair import repair_bag
from actuator_bag.scan import ScanReport, scan_mcap
from bag_helpers import SOURCE, TOPICS, run_messages, synthetic_run

WALL_T0_NS = 1_800_000_000_000_000_000  # 2027: the recorder's wall clock
SPLIT_TOPIC = ('/events/write_split', 'rosbag2_interfaces/msg/WriteSplitEvent')
EXTRA = {
    'diagnostics': ('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray'),
    'rosout': ('/rosout', 'rcl_interfaces/msg/Log'),
    'parameter_events': ('/parameter_events', 'rcl_interfaces/msg/ParameterEvent'),
}
ALL = {**TOPICS, **EXTRA}


def _extra_messages(store, stamps_ns, log_of):
    """(kind, log time, message) of /diagnostics (2 Hz), /rosout and /parameter_events."""
    types = store.types
    time_t = types['builtin_interfaces/msg/Time']

    def stamp(ns):
        return time_t(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))

    header_t = types['std_msgs/msg/Header']
    status_t, kv_t = (
        types['diagnostic_msgs/msg/DiagnosticStatus'],
        types['diagnostic_msgs/msg/KeyValue'],
    )
    for k, ns in enumerate(stamps_ns[::500].tolist()):
        late = k == 3
        statuses = [
            status_t(
                level=1 if late else 0,
                name='actuator_controller',
                message='2 late samples since the last report' if late else 'ok',
                hardware_id='',
                values=[kv_t(key='late', value=str(2 * late))],
            ),
            status_t(level=0, name='actuator_eso', message='ok', hardware_id='', values=[]),
        ]
        yield (
            'diagnostics',
            log_of(ns),
            types['diagnostic_msgs/msg/DiagnosticArray'](
                header=header_t(stamp=stamp(ns), frame_id=''), status=statuses
            ),
        )
    ns = int(stamps_ns[0])
    yield (
        'rosout',
        log_of(ns),
        types['rcl_interfaces/msg/Log'](
            stamp=stamp(ns),
            level=20,
            name='actuator_controller',
            msg='active',
            file='f.py',
            function='f',
            line=1,
        ),
    )
    yield (
        'parameter_events',
        log_of(ns),
        types['rcl_interfaces/msg/ParameterEvent'](
            stamp=stamp(ns),
            node='/actuator_controller',
            new_parameters=[],
            changed_parameters=[],
            deleted_parameters=[],
        ),
    )


def write_rosbag2(
    path: Path, run, storage='mcap', compression=False, split=False, sim_stamps=True
) -> Path:
    """Write a run as ``ros2 bag record -a`` stores it, log times on the wall clock.

    ``sim_stamps``: the header stamps are sim time from 0 (a sim-mode loop), else wall time.
    """
    if not sim_stamps:
        shift = WALL_T0_NS - int(run.stamps_ns[0])
        run.stamps_ns = run.stamps_ns + shift
        run.joint_stamps_ns = run.joint_stamps_ns + shift
    else:
        run.stamps_ns = run.stamps_ns - run.stamps_ns[0]
        run.joint_stamps_ns = run.joint_stamps_ns - run.joint_stamps_ns[0]
    offset = WALL_T0_NS - int(run.stamps_ns[0])  # ros2 bag record's clock: wall time

    store = SOURCE.typestore([t for _, t in ALL.values()])
    msgs = [(k, log + offset, m) for k, log, m in run_messages(run, store)]
    msgs += list(_extra_messages(store, run.stamps_ns, lambda ns: ns + offset + 70_000))
    msgs.sort(key=lambda x: x[1])
    parts = [msgs[: len(msgs) // 2], msgs[len(msgs) // 2 :]] if split else [msgs]
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    written = []
    for i, part in enumerate(parts):
        part_path = path.with_name(f'{path.name}_part{i}') if split else path
        writer = Writer(part_path, version=9, storage_plugin=plugin)
        if compression:  # ros2 bag record --compression-mode file --compression-format zstd
            writer.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
        with writer:
            conns = {
                k: writer.add_connection(name, msgtype, typestore=store)
                for k, (name, msgtype) in ALL.items()
            }
            writer.add_connection(*SPLIT_TOPIC, msgdef='', rihs01='RIHS01_' + '0' * 64)
            for kind, log_ns, msg in part:
                writer.write(conns[kind], log_ns, bytes(store.serialize_cdr(msg, ALL[kind][1])))
        written.append(part_path)
    if split:
        _merge_split(path, written)
    return path


def _merge_split(path: Path, parts: list[Path]) -> None:
    """One bag folder with the parts' files, as rosbag2 leaves a split recording."""
    path.mkdir()
    infos = []
    for i, part in enumerate(parts):
        info = yaml.safe_load((part / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
        (src,) = info['relative_file_paths']
        name = f'{path.name}_{i}{"".join(Path(src).suffixes)}'
        shutil.move(part / src, path / name)
        info['files'][0]['path'] = name
        info['relative_file_paths'] = [name]
        infos.append(info)
        shutil.rmtree(part)
    merged = infos[0]
    merged['relative_file_paths'] = [i['relative_file_paths'][0] for i in infos]
    merged['files'] = [i['files'][0] for i in infos]
    merged['message_count'] = sum(i['message_count'] for i in infos)
    end = max(
        i['starting_time']['nanoseconds_since_epoch'] + i['duration']['nanoseconds'] for i in infos
    )
    merged['duration']['nanoseconds'] = end - merged['starting_time']['nanoseconds_since_epoch']
    counts = {}
    for info in infos:
        for t in info['topics_with_message_count']:
            counts[t['topic_metadata']['name']] = (
                counts.get(t['topic_metadata']['name'], 0) + t['message_count']
            )
    for t in merged['topics_with_message_count']:
        t['message_count'] = counts[t['topic_metadata']['name']]
    (path / 'metadata.yaml').write_text(yaml.safe_dump({'rosbag2_bagfile_information': merged}))


KINDS = [
    pytest.param('mcap', False, False, id='mcap'),
    pytest.param('mcap', True, False, id='mcap-zstd'),
    pytest.param('sqlite3', False, False, id='sqlite3'),
    pytest.param('mcap', False, True, id='mcap-split'),
    pytest.param('sqlite3', False, True, id='sqlite3-split'),
]


@pytest.mark.slow
@pytest.mark.parametrize('storage,compression,split', KINDS)
def test_analysis_reads_a_sim_time_run_that_ros2_bag_record_stored(
    tmp_path, storage, compression, split
):
    run = synthetic_run(duration_s=6.0)
    bag = write_rosbag2(tmp_path / 'rec', run, storage, compression, split)
    files = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert len(files['relative_file_paths']) == (2 if split else 1)
    with Reader(bag) as reader:  # the bag is what rosbag2 would read: every file, every topic
        assert reader.message_count == sum(c.msgcount for c in reader.connections)
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts[SPLIT_TOPIC[0]] == 0 and counts['/rosout'] == 1
    report = analyze_run(load_run(bag, SOURCE, quiet=True))
    assert report.metrics.samples == 6000
    ok = run.t >= 5.0
    assert report.metrics.max_steady_error_rad == pytest.approx(np.max(np.abs(run.error[ok])))
    # Sim-time stamps, wall-clock log times: no delay can be read (it was ~1.8e12 ms).
    assert (report.run.stamp_clock, report.run.log_clock) == ('sim', 'wall')
    assert report.timing['command_latency'] is None
    table = format_table([report])
    assert 'n/a (sim-time stamps, wall-clock log)' in table
    diag = report.run.diagnostics
    assert diag['actuator_controller']['worst'] == 'WARN'
    assert diag['actuator_controller']['levels'] == {'OK': 11, 'WARN': 1}
    assert diag['actuator_controller']['reasons'] == ['2 late samples since the last report']
    assert diag['actuator_eso'] == {
        'levels': {'OK': 12},
        'worst': 'OK',
        'reasons': [],
        'before_run': {},
        'after_run': {},
    }
    assert 'actuator_controller WARN (OK 11 WARN 1): 2 late samples' in table


@pytest.mark.slow
def test_wall_clock_stamps_give_the_recorder_delay(tmp_path):
    run = synthetic_run(duration_s=2.0)
    bag = write_rosbag2(tmp_path / 'rec', run, sim_stamps=False)
    report = analyze_run(load_run(bag, SOURCE, quiet=True))
    assert (report.run.stamp_clock, report.run.log_clock) == ('wall', 'wall')
    assert report.timing['command_latency']['p50_s'] == pytest.approx(
        float(np.median(run.latency_ns)) * 1e-9, rel=1e-6
    )


@pytest.mark.slow
def test_a_run_shorter_than_the_steady_window_says_so(tmp_path):
    run = synthetic_run(duration_s=4.0)
    report = analyze_run(load_run(write_rosbag2(tmp_path / 'short', run), SOURCE, quiet=True))
    assert math.isnan(report.metrics.max_steady_error_rad)
    table = format_table([report])
    assert 'none: the run lasts 3.999 s, the window starts at 5 s' in table
    assert 'n/a (run shorter than the steady window)' in table
    assert '5.0-3.999' not in table
    assert report.as_dict()['steady_window_empty'] is True


@pytest.mark.slow
def test_repair_keeps_topics_that_have_no_message(tmp_path):
    run = synthetic_run(duration_s=1.0)
    bag = write_rosbag2(tmp_path / 'rec', run, 'mcap')
    (mcap,) = bag.glob('*.mcap')
    # rosbag2 writes the channel of a topic without messages only in the summary: make the data
    # section so (rosbags writes every channel there), then repair a copy without metadata.yaml.
    damaged = tmp_path / 'summary_only'
    damaged.mkdir()
    _drop_data_channel(mcap, damaged / mcap.name, SPLIT_TOPIC[0])
    result = repair_bag(damaged, tmp_path / 'fixed', quiet=True)
    assert result.summary.counts[SPLIT_TOPIC[0]] == 0
    with Reader(tmp_path / 'fixed') as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    with Reader(bag) as reader:
        assert counts == {c.topic: c.msgcount for c in reader.connections}


def _drop_data_channel(src: Path, dst: Path, topic: str) -> None:
    """Copy an MCAP file with the channel of ``topic`` in its summary only, as rosbag2 has it."""
    from mcap.reader import make_reader
    from mcap.records import Channel
    from mcap.writer import Writer as McapWriter

    with open(src, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        messages = [(c.id, m) for _, c, m in reader.iter_messages()]
    with open(dst, 'wb') as f:
        writer = McapWriter(f)
        writer.start(profile='ros2', library='test')
        schemas = {
            sid: writer.register_schema(s.name, s.encoding, s.data)
            for sid, s in summary.schemas.items()
        }
        channels, silent = {}, None
        for cid, c in summary.channels.items():
            if c.topic == topic:
                silent = c
                continue
            channels[cid] = writer.register_channel(
                c.topic, c.message_encoding, schemas[c.schema_id], dict(c.metadata)
            )
        for cid, m in messages:
            writer.add_message(channels[cid], m.log_time, m.data, m.publish_time)
        # Into the summary only (the writer's own bookkeeping): no record in the data section.
        new_id = max(channels.values()) + 1
        writer._Writer__channels[new_id] = Channel(
            id=new_id,
            topic=silent.topic,
            message_encoding=silent.message_encoding,
            schema_id=schemas[silent.schema_id],
            metadata=dict(silent.metadata),
        )
        writer._Writer__statistics.channel_count += 1
        writer.finish()
    report = ScanReport(path=dst, file_size=dst.stat().st_size)
    data_channels = [r.topic for r in scan_mcap(dst, report) if isinstance(r, Channel)]
    assert topic not in data_channels and report.complete


def test_player_skips_a_topic_whose_type_is_not_installed(ros_process, tmp_path):
    """``-a`` bag: every installed type plays, WriteSplitEvent is skipped with one warning."""
    bag = write_rosbag2(tmp_path / 'rec', synthetic_run(duration_s=0.5), 'sqlite3')
    player = ros_process('actuator_bag', 'player', [str(bag), '--rate', '10'])
    assert player.wait(60) == 0, player.describe()
    out = player.stdout + player.stderr
    assert 'skipping 1 topic(s) whose type is not installed: /events/write_split' in out
    line = next(x for x in player.stdout.splitlines() if x.startswith('player: done'))
    assert '/rosout=1' in line and '/diagnostics=1' in line and '/controller/state=500' in line
    # Asked for by name, the same topic is an error that names it.
    named = ros_process('actuator_bag', 'player', [str(bag), '--topics', SPLIT_TOPIC[0]])
    assert named.wait(60) == 1
    assert 'is not installed' in named.stderr and SPLIT_TOPIC[0] in named.stderr
