# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""In-process recording: the composed lockstep writes its bag through a pipe, losing nothing.

The frames (actuator_bag.spool) on their own; the tap (actuator_bag.tap) on a lifecycle
publisher; and whole runs: the bag of a container that records itself holds the same messages
as the recorder process's bag of the same sim run, and a full disk stops the recording, not the
loop, with one line and a bag that bag_repair recovers.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader

from actuator_bag.bag_qos import QosProfile
from actuator_bag.datafile import FULL_AFTER_ENV
from actuator_bag.errors import BagError
from actuator_bag.spool import HEADER, FrameSpool, SpoolError, read_frames, write_bag

#: The loop topics a sim run publishes the same bytes on whichever way it is recorded
#: (controller/state carries the compute time of its sample).
DETERMINISTIC = ('/joint_states', '/eso/estimate', '/current_command', '/plant/truth')
COMMAND = 'actuator_msgs/msg/CurrentCommand'


def _messages(bag: Path) -> dict[str, list[tuple[int, bytes]]]:
    """(log time, raw bytes) per topic, every message decoded on the way (types checked)."""
    out: dict[str, list[tuple[int, bytes]]] = {}
    with AnyReader([bag]) as reader:
        for conn, log_ns, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            out.setdefault(conn.topic, []).append((log_ns, bytes(raw)))
    return out


def _command(k: int) -> bytes:
    """Return a CurrentCommand in CDR: stamp k ms, empty frame_id, current k mA, no safe stop."""
    import struct

    stamp = struct.pack('<iI', k // 1000, k % 1000 * 1_000_000)
    body = stamp + struct.pack('<I', 1) + b'\0' + bytes(3)
    return b'\0\x01\0\0' + body + struct.pack('<d', k * 1e-3) + b'\0' + bytes(3)


def _write_in_thread(read_fd: int, out: Path):
    """Run write_bag on ``read_fd`` in a thread; return (thread, result dict)."""
    result: dict = {}

    def run():
        with os.fdopen(read_fd, 'rb') as stream:
            try:
                result['writer'] = write_bag(stream, out)
            except BagError as err:
                result['error'] = err

    thread = threading.Thread(target=run)
    thread.start()
    return thread, result


def test_frames_through_a_pipe_make_the_bag_with_every_message_in_order(tmp_path):
    """Announced topic, its QoS, 3000 messages in small batches: all in the bag, in order."""
    read_fd, write_fd = os.pipe()
    thread, result = _write_in_thread(read_fd, tmp_path / 'bag')
    spool = FrameSpool(write_fd, batch_bytes=4096)
    qos = QosProfile(reliability='best_effort', depth=7)
    spool.add_topic(3, '/current_command', COMMAND, [qos])
    sent = [(1_000_000 * k, _command(k)) for k in range(3000)]
    for log_ns, data in sent:
        spool.add(3, log_ns, data)
    assert 0 < spool.sent < spool.frames == 3000  # batches went out while adding
    spool.flush()
    assert spool.sent == 3000
    os.close(write_fd)
    thread.join(30)
    assert 'error' not in result
    assert _messages(tmp_path / 'bag') == {'/current_command': sent}
    metadata = (tmp_path / 'bag' / 'metadata.yaml').read_text()
    assert 'in-process recording' in metadata and 'depth: 7' in metadata


def test_a_stream_cut_inside_a_frame_is_one_error_and_what_came_is_kept(tmp_path):
    """The sender died mid-write: BagError naming the cut, the whole frames before are in."""
    read_fd, write_fd = os.pipe()
    thread, result = _write_in_thread(read_fd, tmp_path / 'bag')
    spool = FrameSpool(write_fd)
    spool.add_topic(0, '/current_command', COMMAND, [QosProfile()])
    for k in range(10):
        spool.add(0, k, _command(k))
    spool.flush()
    os.write(write_fd, HEADER.pack(0, 10, 40) + b'\0' * 12)  # 12 of 40 bytes
    os.close(write_fd)
    thread.join(30)
    assert 'ended inside a frame (' in str(result['error'])
    assert len(_messages(tmp_path / 'bag')['/current_command']) == 10


def test_a_message_of_a_topic_never_announced_is_refused(tmp_path):
    """A frame must name an announced topic: the writer stops with one line."""
    read_fd, write_fd = os.pipe()
    thread, result = _write_in_thread(read_fd, tmp_path / 'bag')
    spool = FrameSpool(write_fd)
    spool.add(5, 0, _command(0))
    spool.flush()
    os.close(write_fd)
    thread.join(30)
    assert 'a message of topic 5, which was never announced' in str(result['error'])


def test_the_spool_says_how_many_messages_the_gone_writer_did_not_get():
    """Reader closed: SpoolError with the count; the batch stays for nothing to be hidden."""
    read_fd, write_fd = os.pipe()
    spool = FrameSpool(write_fd, batch_bytes=1 << 30)
    spool.add_topic(0, '/current_command', COMMAND, [QosProfile()])  # handed over at once
    assert not spool.batch and os.read(read_fd, 1 << 16)
    os.close(read_fd)
    for k in range(25):
        spool.add(0, k, _command(k))
    with pytest.raises(SpoolError, match='25 messages not recorded'):
        spool.flush()
    assert spool.sent == 0 and spool.batch
    os.close(write_fd)


def test_a_stream_without_a_frame_leaves_no_bag(tmp_path):
    """The loop's process ended before its first frame (bad arguments): nothing is created."""
    import io

    assert write_bag(io.BytesIO(b''), tmp_path / 'bag') is None
    assert not (tmp_path / 'bag').exists()


def test_frames_split_across_reads_come_out_whole():
    """A frame cut by the pipe's read size is joined with the next read."""
    import io

    frames = [(0, k, bytes([k]) * (k * 7 % 50)) for k in range(200)]
    stream = io.BytesIO(b''.join(HEADER.pack(i, t, len(d)) + d for i, t, d in frames))
    assert list(read_frames(stream, read_size=13)) == frames


@pytest.mark.slow
def test_the_writer_process_on_a_full_disk_exits_1_with_one_line_and_a_repairable_bag(tmp_path):
    """ENOSPC mid-run: exit 1, one line naming bag_repair; the repair has the durable messages."""
    from actuator_bag.repair import repair_bag

    out = tmp_path / 'bag'
    env = {**os.environ, FULL_AFTER_ENV: '60000'}
    writer = subprocess.Popen(
        [sys.executable, '-m', 'actuator_bag.spool', '--output', str(out), '--chunk-size', '4096'],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    spool = FrameSpool(writer.stdin.fileno(), batch_bytes=2048)
    spool.add_topic(0, '/current_command', COMMAND, [QosProfile()])
    with pytest.raises(SpoolError, match='messages not recorded'):
        for k in range(1_000_000):
            spool.add(0, k, _command(k))
    writer.stdin.close()
    writer.wait(30)
    lines = writer.stderr.read().decode().strip().splitlines()
    writer.stdout.close()
    writer.stderr.close()
    assert writer.returncode == 1 and len(lines) == 1, lines
    assert 'No space left on device' in lines[0] and f'run bag_repair {out}' in lines[0]
    result = repair_bag(out, tmp_path / 'fixed', quiet=True)
    assert 0 < result.summary.message_count < spool.frames


# ------------------------------------------------------------------------ the tap, in rclpy
@pytest.mark.usefixtures('rclpy_context')
def test_the_tap_records_what_an_active_lifecycle_publisher_sends_and_counts_as_a_subscriber(
    rclpy_context, tmp_path
):
    """Inactive: nothing sent, nothing recorded; active: each message, on the sim clock."""
    from rclpy.lifecycle import LifecycleNode
    from rosgraph_msgs.msg import Clock

    from actuator_bag.tap import InProcessRecording, RecordedPublisher
    from actuator_msgs.msg import CurrentCommand
    from actuator_ros.conversions import ns_to_stamp

    recording = InProcessRecording(tmp_path / 'bag', topics=['current_command'])
    node = LifecycleNode('tapped', context=rclpy_context)
    try:
        raw_clock = node.create_lifecycle_publisher(Clock, '/clock', 10)
        raw_command = node.create_lifecycle_publisher(CurrentCommand, 'current_command', 10)
        clock = recording.hook(node, raw_clock, Clock)
        command = recording.hook(node, raw_command, CurrentCommand)
        other = node.create_publisher(CurrentCommand, 'elsewhere', 10)
        assert recording.hook(node, other, CurrentCommand) is other  # not a recorded topic
        assert isinstance(command, RecordedPublisher) and command.inner is raw_command
        assert command.get_subscription_count() == raw_command.get_subscription_count() + 1
        assert clock.get_subscription_count() == raw_clock.get_subscription_count()  # followed
        msg = CurrentCommand(current_a=0.25)
        command.publish(msg)  # inactive: rclpy sends nothing, so nothing is recorded
        node.trigger_configure()
        node.trigger_activate()
        for k in (1, 2, 3):
            clock.publish(Clock(clock=ns_to_stamp(k * 1_000_000)))
            msg.header.stamp = ns_to_stamp(k * 1_000_000)
            command.publish(msg)
    finally:
        node.destroy_node()
    assert recording.close()
    logged = [t for t, _ in _messages(tmp_path / 'bag')['/current_command']]
    assert logged == [1_000_000, 2_000_000, 3_000_000]


@pytest.mark.usefixtures('rclpy_context')
def test_a_node_in_real_time_stops_the_in_process_recording_with_one_line(
    rclpy_context, tmp_path, capfd
):
    """A realtime node: nothing wrapped, one line saying why and what to use; close is False."""
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    from actuator_bag.tap import InProcessRecording
    from actuator_msgs.msg import CurrentCommand

    recording = InProcessRecording(tmp_path / 'bag')
    node = Node(
        'joint',
        context=rclpy_context,
        parameter_overrides=[Parameter('mode', value='realtime')],
        automatically_declare_parameters_from_overrides=True,
    )
    try:
        publisher = node.create_publisher(CurrentCommand, 'current_command', 10)
        assert recording.hook(node, publisher, CurrentCommand) is publisher
    finally:
        node.destroy_node()
    assert not recording.close()
    lines = [line for line in capfd.readouterr().err.splitlines() if 'loop_container' in line]
    assert lines == [
        'loop_container: in-process recording stopped: it is for sim time, and /joint runs in '
        'realtime mode (a full pipe would hold up its loop): nothing of this run is recorded; '
        'record a real-time run with the recorder process'
    ]


# ------------------------------------------------------------------------------ whole runs
def _sim_run(name: str, root: Path, duration_s: float = 2.0, **kwargs):
    """Run a composed lockstep of the paper's case under ``root``; return its RunResult."""
    from actuator_bringup.runner import run_closed_loop

    return run_closed_loop(
        'case2_pp_nftsmc_eso',
        'sim',
        duration_s,
        bag_root=root / 'bags' / name,
        results_root=root / 'runs' / name,
        quiet=True,
        composed=True,
        **kwargs,
    )


def test_an_in_process_bag_holds_what_the_recorder_process_records(isolated):
    """Same sim run, both ways: the four deterministic topics byte for byte, every topic whole.

    The in-process run has no recorder process, and its bag says how it was recorded.
    """
    through_dds = _sim_run('dds', isolated)
    in_process = _sim_run('tap', isolated, record_in_process=True)
    assert through_dds.exit_codes == {'recorder': 0, 'loop': 0}
    assert in_process.exit_codes == {'loop': 0}
    dds, tap = _messages(through_dds.bag), _messages(in_process.bag)
    for topic in DETERMINISTIC:
        assert len(tap[topic]) >= 2000, topic
        assert [d for _, d in tap[topic]] == [d for _, d in dds[topic]], topic
    assert len(tap['/controller/state']) == len(dds['/controller/state']) >= 2000
    assert tap['/diagnostics']  # every node's reports are in too
    # log times on the sim clock: each sample's messages at its /clock
    stamps = [t for t, _ in tap['/joint_states']]
    assert stamps == sorted(stamps) and stamps[1] - stamps[0] == 1_000_000
    metadata = (in_process.bag / 'metadata.yaml').read_text()
    assert 'in-process recording' in metadata


def test_a_full_disk_stops_the_in_process_recording_not_the_loop(isolated, monkeypatch):
    """ENOSPC: the loop runs to its end, one line each from writer and container, exit 1.

    bag_repair recovers what reached the disk.
    """
    from actuator_bag.repair import repair_bag
    from actuator_bringup.supervisor import process_log

    # past the first chunk (1 MiB before compression, about 430 kB), in the second of about five
    monkeypatch.setenv(FULL_AFTER_ENV, '600000')
    result = _sim_run('full', isolated, 5.0, record_in_process=True)
    monkeypatch.delenv(FULL_AFTER_ENV)
    log = process_log(result.run_dir, 'loop')
    assert result.exit_codes == {'loop': 1}, log[-2000:]
    assert 'run of 5.0 s complete' in log, log[-2000:]
    assert 'No space left on device' in log and f'run bag_repair {result.bag}' in log
    assert 'messages are on disk' in log and 'received ones were lost' in log
    assert 'in-process recording stopped: the bag writer took no more' in log
    assert 'Traceback' not in log
    repaired = repair_bag(result.bag, isolated / 'fixed', quiet=True)
    assert repaired.summary.message_count > 0


# ---------------------------------------------------------------------- where it is offered
def test_compose_moves_the_recording_into_the_container_in_sim_time_only(tmp_path):
    """The recorder's bag goes to the container's --record; refused where it cannot hold."""
    from actuator_bringup.composition import compose
    from actuator_bringup.ros_arguments import ros_arguments
    from actuator_bringup.run_description import closed_loop

    bag = tmp_path / 'bag'
    specs = compose(closed_loop('sim', 5.0, bag=bag), record_in_process=True)
    assert [s.key for s in specs] == ['loop']
    args = ros_arguments(specs[0], None)
    assert args[: args.index('--ros-args')] == [
        '--nodes',
        'plant',
        'controller',
        'eso',
        '--record',
        str(bag),
    ]
    # the joint still waits for the recorder: the tap counts as its subscriber
    (plant,) = [m for m in specs[0].members if m.key == 'plant']
    assert plant.parameters['wait_for_subscribers'] == 3
    assert '--record' not in ros_arguments(compose(closed_loop('sim', 5.0))[-1], None)
    for specs, why in (
        (closed_loop('realtime', 5.0), 'is for sim time'),
        (closed_loop('sim', 5.0, record=False), 'needs the recorder'),
    ):
        with pytest.raises(ValueError, match=why):
            compose(specs, record_in_process=True)


@pytest.mark.parametrize(
    'args, why',
    [
        (['--mode', 'sim'], 'needs --composed and --mode sim'),
        (['--mode', 'realtime', '--composed'], 'needs --composed and --mode sim'),
        (['--mode', 'sim', '--composed', '--no-record'], 'not with --no-record'),
    ],
)
def test_bringup_refuses_record_in_process_where_it_cannot_hold(args, why, capsys):
    """One usage line, exit 2, before anything starts."""
    from actuator_bringup.runner import main

    with pytest.raises(SystemExit) as stop:
        main([*args, '--record-in-process'])
    assert stop.value.code == 2
    assert why in capsys.readouterr().err


def test_the_container_refuses_a_bag_folder_that_exists(tmp_path, ros_env):
    """No overwrite: one line and exit 2 before any node is built."""
    proc = subprocess.run(
        [sys.executable, '-m', 'actuator_bringup.container', '--record', str(tmp_path)],
        capture_output=True,
        text=True,
        env=ros_env,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip() == f'loop_container: {tmp_path} exists already, not overwriting'
