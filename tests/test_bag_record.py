# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Recorder, player and repair against a live ROS graph: installed executables, isolated domain.

The load they record comes from ``bag_load_publisher.py``, started as a separate process.
"""

from __future__ import annotations

import argparse
import hashlib
import signal
import sys
import time
from pathlib import Path

# No rclpy at the top: the module collects where rclpy is unimportable (the unit set runs without
# ROS); its ROS tests start the installed executables, so a broken install fails them, it never
# skips them.
import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader

from bag_load_publisher import TOPICS
from ros_helpers import RosProcess, wait_for_signal_handler

N = 3000


def _publisher(ros_env: dict, tmp_path: Path, *args: str) -> RosProcess:
    """Start the load publisher (bag_load_publisher.py) as its own process."""
    return RosProcess.python(
        Path(__file__).with_name('bag_load_publisher.py'),
        [str(a) for a in args],
        env=ros_env,
        log_dir=tmp_path / 'processes',
        name='load_publisher',
    )


def _start_recorder(ros_process, out: Path, *extra: str) -> RosProcess:
    """Start the installed recorder writing to ``out`` and wait until it subscribed."""
    proc = ros_process('actuator_bag', 'recorder', ['-o', str(out), *extra])
    proc.wait_for_output(r'recording \d+ topics', timeout=30)
    return proc


def _bag_messages(path: Path) -> dict[str, list[bytes]]:
    """Raw messages per topic, every one decoded on the way.

    AnyReader also checks the type hashes.
    """
    out: dict[str, list[bytes]] = {}
    with AnyReader([path]) as reader:
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            out.setdefault(conn.topic, []).append(bytes(raw))
    return out


def _stamps(path: Path) -> dict[str, list[int]]:
    """header.stamp.nanosec of each message, per topic, in bag order."""
    out: dict[str, list[int]] = {}
    with AnyReader([path]) as reader:
        for conn, _, raw in reader.messages():
            out.setdefault(conn.topic, []).append(
                reader.deserialize(raw, conn.msgtype).header.stamp.nanosec
            )
    return out


def test_records_every_message_at_1khz(ros_env, ros_process, tmp_path: Path) -> None:
    """N messages at 1 kHz on each of five topics.

    The bag holds exactly N per topic, in order, all decodable.
    """
    bag = tmp_path / 'rec'
    recorder = _start_recorder(ros_process, bag)
    pub = _publisher(ros_env, tmp_path, N)
    assert pub.wait(90) == 0, pub.describe()
    assert recorder.stop() == 0 and recorder.stopped_by == 'SIGINT', recorder.describe()
    stamps = _stamps(bag)
    assert {k: len(v) for k, v in stamps.items()} == {t: N for t in TOPICS}, recorder.stdout
    assert all(v == list(range(N)) for v in stamps.values())
    summary = [line for line in recorder.stdout.splitlines() if line.startswith('recorder: wrote')]
    assert len(summary) == 1 and f'{5 * N} messages' in summary[0] and str(bag) in summary[0]
    assert 'Traceback' not in recorder.stderr
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    offered = info['topics_with_message_count'][0]['topic_metadata']['offered_qos_profiles']
    assert offered and offered[0]['reliability'] == 'reliable'


def test_best_effort_publisher_is_matched(ros_env, ros_process, tmp_path: Path) -> None:
    """A best-effort 1 kHz publisher is recorded too, and its offered QoS says best_effort."""
    bag = tmp_path / 'be'
    recorder = _start_recorder(ros_process, bag)
    pub = _publisher(ros_env, tmp_path, 500, '--reliability', 'best_effort')
    assert pub.wait(60) == 0, pub.describe()
    assert recorder.stop() == 0, recorder.describe()
    with Reader(bag) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        qos = {c.topic: c.ext.offered_qos_profiles[0].reliability.name for c in reader.connections}
    assert set(counts) == set(TOPICS) and all(n >= 490 for n in counts.values()), counts
    assert set(qos.values()) == {'BEST_EFFORT'}


def test_sim_time_log_times_follow_clock(ros_env, ros_process, tmp_path: Path) -> None:
    """With use_sim_time the log time is the node's ROS time (from /clock), not wall time.

    The lag bound allows for load.
    """
    bag = tmp_path / 'sim'
    recorder = _start_recorder(ros_process, bag, '--ros-args', '-p', 'use_sim_time:=true')
    pub = _publisher(ros_env, tmp_path, 1000, '--clock')
    assert pub.wait(60) == 0, pub.describe()
    assert recorder.stop() == 0, recorder.describe()
    with AnyReader([bag]) as reader:
        lags = []
        for conn, log_ns, raw in reader.messages():
            stamp = reader.deserialize(raw, conn.msgtype).header.stamp
            lags.append(log_ns - (stamp.sec * 1_000_000_000 + stamp.nanosec))
    assert len(lags) > 4000
    assert all(-5_000_000 <= lag <= 2_000_000_000 for lag in lags), (
        min(lags),
        max(lags),
    )  # wall time: ~1.8e18


def test_sigterm_closes_the_bag(ros_env, ros_process, tmp_path: Path) -> None:
    """SIGTERM ends the recorder like SIGINT: exit 0, metadata.yaml written, summary printed.

    Reliable subscriptions (the default is best effort), so that every message sent is owed to
    the bag and the count is exact.
    """
    bag = tmp_path / 'term'
    recorder = _start_recorder(ros_process, bag, '--reliability', 'reliable')
    pub = _publisher(ros_env, tmp_path, 300)
    assert pub.wait(60) == 0, pub.describe()
    recorder.popen.send_signal(signal.SIGTERM)
    assert recorder.wait(20) == 0, recorder.describe()
    assert (bag / 'metadata.yaml').is_file()
    assert 'recorder: wrote' in recorder.stdout and 'Traceback' not in recorder.stderr
    with Reader(bag) as reader:
        assert reader.message_count == 5 * 300


def test_sigkill_mid_run_then_repair(ros_env, ros_process, tmp_path: Path) -> None:
    """SIGKILL (kill -9) while recording: bag_repair recovers the flushed part, original untouched.

    The recovered part is not empty, and all of it decodes.
    """
    bag = tmp_path / 'killed'
    recorder = _start_recorder(ros_process, bag, '--flush-interval', '0.5')
    pub = _publisher(ros_env, tmp_path, 4000)
    pub.wait_for_output('publishing', timeout=30)
    time.sleep(2.5)
    assert pub.running
    recorder.popen.send_signal(signal.SIGKILL)
    recorder.popen.wait(10)
    pub.wait(60)
    assert not (bag / 'metadata.yaml').exists()
    mcap = next(bag.glob('*.mcap'))
    before = hashlib.sha256(mcap.read_bytes()).hexdigest()
    with pytest.raises(FileNotFoundError, match='metadata'):
        Reader(bag).open()
    repair = RosProcess.installed(
        'actuator_bag',
        'bag_repair',
        [str(bag), '-o', str(tmp_path / 'fixed')],
        env=ros_env,
        log_dir=tmp_path / 'processes',
    )
    assert repair.wait(60) == 0, repair.describe()
    assert repair.stdout.startswith('repaired ')
    messages = _bag_messages(tmp_path / 'fixed')
    counts = {k: len(v) for k, v in messages.items()}
    assert set(counts) == set(TOPICS)
    assert all(500 <= n < 4000 for n in counts.values()), counts
    assert hashlib.sha256(mcap.read_bytes()).hexdigest() == before


def test_replay_reproduces_the_recording(ros_env, ros_process, tmp_path: Path) -> None:
    """Record -> play -> record again: same count and bytes per topic."""
    first = tmp_path / 'first'
    recorder = _start_recorder(ros_process, first)
    pub = _publisher(ros_env, tmp_path, 2000)
    assert pub.wait(60) == 0, pub.describe()
    assert recorder.stop() == 0, recorder.describe()
    second = tmp_path / 'second'
    # Reliable on both ends: the comparison is about the bytes, and a reliable pair cannot drop
    # a message even when the machine is loaded (best effort may, by design).
    recorder2 = _start_recorder(ros_process, second, '--reliability', 'reliable')
    player = ros_process(
        'actuator_bag',
        'player',
        [str(first), '--wait-for-subscribers', '1', '--start-delay', '2.0'],
    )
    assert player.wait(60) == 0, player.describe()
    assert 'player: done: published 10000 messages' in player.stdout
    time.sleep(0.5)
    assert recorder2.stop() == 0, recorder2.describe()
    a, b = _bag_messages(first), _bag_messages(second)
    assert (
        {k: len(v) for k, v in b.items()}
        == {k: len(v) for k, v in a.items()}
        == {t: 2000 for t in TOPICS}
    )
    assert all(a[t] == b[t] for t in TOPICS)
    with Reader(first) as ra, Reader(second) as rb:
        assert abs(rb.duration - ra.duration) < 0.2 * ra.duration


def test_player_rate_and_topic_selection(ros_env, ros_process, tmp_path: Path) -> None:
    """Rate 2 halves the playing time; a topic selection plays only those topics."""
    from bag_helpers import synthetic_run, write_run_bag

    src = write_run_bag(tmp_path / 'src', synthetic_run(duration_s=2.0))
    out = tmp_path / 'sel'
    recorder = _start_recorder(ros_process, out)
    player = ros_process(
        'actuator_bag',
        'player',
        [
            str(src),
            '--rate',
            '2',
            '--topics',
            'controller/state',
            '/joint_states',
            '--wait-for-subscribers',
            '1',
            '--start-delay',
            '1.0',
        ],
    )
    assert player.wait(60) == 0, player.describe()
    line = next(x for x in player.stdout.splitlines() if x.startswith('player: done'))
    seconds = float(line.split(' in ')[1].split(' s ')[0])
    assert 0.9 <= seconds <= 1.3, line
    time.sleep(0.5)
    assert recorder.stop() == 0
    with Reader(out) as reader:
        assert {c.topic: c.msgcount for c in reader.connections} == {
            '/controller/state': 2000,
            '/joint_states': 2000,
        }


@pytest.mark.parametrize(
    'exe, args, expect',
    [
        ('recorder', ['-o', '{tmp}'], 'exists already'),
        ('recorder', ['--topics', 'mystery'], "topic 'mystery' is not a system topic"),
        ('recorder', ['--topics', 'x:nowhere_msgs/msg/Nothing'], 'not installed'),
        ('player', ['{tmp}/missing'], 'does not exist'),
        ('player', ['{tmp}', '--rate', '0'], 'rate must be'),
        ('player', [], 'no bag given'),
    ],
)
def test_bad_input_one_line_error(
    ros_process, tmp_path: Path, exe: str, args: list, expect: str
) -> None:
    """Bad arguments: exit code 1, one error line naming the problem, no traceback."""
    proc = ros_process('actuator_bag', exe, [a.replace('{tmp}', str(tmp_path)) for a in args])
    assert proc.wait(30) == 1, proc.describe()
    errors = [x for x in proc.stderr.splitlines() if x.startswith(f'{exe}: error:')]
    assert len(errors) == 1 and expect in errors[0], proc.describe()
    assert 'Traceback' not in proc.stderr


def test_player_unknown_topic(ros_process, tmp_path: Path) -> None:
    """Selecting a topic the bag lacks names the topics it has."""
    from bag_helpers import synthetic_run, write_run_bag

    src = write_run_bag(tmp_path / 'src', synthetic_run(duration_s=0.1), topics=('state',))
    proc = ros_process('actuator_bag', 'player', [str(src), '--topics', 'nope'])
    assert proc.wait(30) == 1
    assert (
        'no topic /nope; the bag has: /controller/state' in proc.stderr
        and 'Traceback' not in proc.stderr
    )


@pytest.mark.unit  # recording.py is ROS-free
def test_a_system_topic_under_a_namespace_has_its_type() -> None:
    """Several joints: /joint2/eso/estimate is the StateEstimate topic of joint 2."""
    from actuator_bag.errors import BagError
    from actuator_bag.recording import parse_topic

    assert parse_topic('/joint2/eso/estimate') == (
        '/joint2/eso/estimate',
        'actuator_msgs/msg/StateEstimate',
    )
    assert parse_topic('/joint1/joint_states')[1] == 'sensor_msgs/msg/JointState'
    for wrong in ('/joint1/estimate', '/joint1/clock', '/joint1/xjoint_states'):
        with pytest.raises(BagError, match='is not a system topic'):
            parse_topic(wrong)


@pytest.mark.parametrize(
    'package, exe',
    [
        ('actuator_bag', 'recorder'),
        ('actuator_bag', 'player'),
        ('actuator_bag', 'bag_repair'),
        ('actuator_analysis', 'bag_analyze'),
        ('actuator_analysis', 'bag_identify'),
    ],
)
def test_help(ros_process, package: str, exe: str) -> None:
    """Every executable of the bag tools answers --help with usage and exit code 0."""
    proc = ros_process(package, exe, ['--help'])
    assert proc.wait(30) == 0, proc.describe()
    assert proc.stdout.startswith('usage: ')


# ------------------------------------------------- full disk, parameters, signals at any moment
def test_full_disk_stops_the_recorder_at_once(ros_env, ros_process, tmp_path: Path) -> None:
    """Disk full while recording (real ENOSPC): exit 1 by itself, one error line.

    bag_repair recovers what it said.
    """
    from actuator_bag.bag_format import mcap_name
    from actuator_bag.datafile import FULL_AFTER_ENV

    bag = tmp_path / 'full'
    env = {**ros_env, FULL_AFTER_ENV: '60000'}
    recorder = ros_process(
        'actuator_bag', 'recorder', ['-o', str(bag), '--flush-interval', '0.2'], env=env
    )
    recorder.wait_for_output(r'recording \d+ topics', timeout=30)
    pub = _publisher(ros_env, tmp_path, 4000)
    pub.wait_for_output('publishing', timeout=30)
    started = time.monotonic()
    code = recorder.wait(20)
    assert code == 1 and recorder.stopped_by == 'exit', recorder.describe()
    assert time.monotonic() - started < 4.0 and pub.running  # noticed mid-run, not at the end
    errors = [x for x in recorder.stderr.splitlines() if x.startswith('recorder: error:')]
    assert len(errors) == 1 and 'No space left on device (ENOSPC)' in errors[0], (
        recorder.describe()
    )
    assert f'run bag_repair {bag}' in errors[0] and 'Traceback' not in recorder.stderr
    on_disk = int(errors[0].split('recording stopped: ')[1].split(' messages are on disk')[0])
    assert on_disk > 0 and (bag / mcap_name(bag)).stat().st_size <= 60000
    assert not (bag / 'metadata.yaml').exists()
    pub.stop()
    repair = RosProcess.installed(
        'actuator_bag',
        'bag_repair',
        [str(bag), '-o', str(tmp_path / 'fixed'), '-q'],
        env=ros_env,
        log_dir=tmp_path / 'processes',
    )
    assert repair.wait(60) == 0, repair.describe()
    assert sum(len(v) for v in _bag_messages(tmp_path / 'fixed').values()) == on_disk
    assert '0 bytes not recoverable, 0 messages lost' in repair.stdout


@pytest.mark.parametrize(
    'args, names',
    [
        (['-p', 'queue_depth:=many'], ['queue_depth']),
        (['-p', 'queue_depth:=0'], ['queue_depth', '[1, ']),
        (['-p', 'flush_interval:=true'], ['flush_interval']),
        (['-p', 'reliability:=sometimes'], ['reliability', 'best_effort']),
        (['-p', 'topics:=7'], ['topics']),
        (['-p', 'queu_depth:=5'], ['queu_depth', "did you mean 'queue_depth'"]),
    ],
)
def test_recorder_refuses_bad_parameters(
    ros_process, tmp_path: Path, args: list, names: list
) -> None:
    """A wrong type, a value out of range or a misspelled name: one line naming it, exit 2.

    No bag is created.
    """
    bag = tmp_path / 'never'
    proc = ros_process('actuator_bag', 'recorder', ['-o', str(bag), '--ros-args', *args])
    assert proc.wait(30) == 2, proc.describe()
    lines = [x for x in proc.stderr.splitlines() if x.startswith('recorder: ')]
    assert len(lines) == 1 and all(n in lines[0] for n in names), proc.describe()
    assert 'Traceback' not in proc.stderr and not bag.exists()


def test_recorder_allows_unknown_parameters_when_asked(ros_process, tmp_path: Path) -> None:
    """allow_unknown_parameters:=true turns a misspelled name into a warning; the recorder runs."""
    bag = tmp_path / 'ok'
    proc = _start_recorder(
        ros_process,
        bag,
        '--ros-args',
        '-p',
        'allow_unknown_parameters:=true',
        '-p',
        'queu_depth:=5',
    )
    assert proc.stop() == 0 and (bag / 'metadata.yaml').is_file(), proc.describe()
    assert 'queu_depth' in proc.stderr + proc.stdout


def test_recorder_parameters_have_descriptions(rclpy_context, tmp_path: Path) -> None:
    """Every parameter the recorder declares has a description (ros2 param describe shows it)."""
    from actuator_bag.recorder_node import RecorderNode
    from actuator_bag.recording import add_arguments

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    node = RecorderNode(parser.parse_args(['-o', str(tmp_path / 'desc')]), context=rclpy_context)
    try:
        names = sorted(n for n in node._parameters if n != 'use_sim_time')  # noqa: SLF001
        assert {
            'topics',
            'record_clock',
            'output',
            'queue_depth',
            'reliability',
            'flush_interval',
            'chunk_size',
            'allow_unknown_parameters',
        } <= set(names)
        assert all(d.description for d in node.describe_parameters(names)), names
        node.finish()
    finally:
        node.destroy_node()


@pytest.mark.parametrize('exe', ['recorder', 'player'])
def test_entry_point_quiets_signals_before_rclpy(exe: str) -> None:
    """The recorder and player start at actuator_bag.entry, whose import loads no rclpy.

    So signals go quiet first.
    """
    import importlib.metadata
    import subprocess

    scripts = {
        ep.name: ep.value
        for ep in importlib.metadata.distribution('actuator_bag').entry_points
        if ep.group == 'console_scripts'
    }
    assert scripts[exe] == f'actuator_bag.entry:{exe}'
    probe = subprocess.run(
        [
            sys.executable,
            '-c',
            'import sys, actuator_bag.entry; '
            'print(sorted(m for m in sys.modules if m.split(".")[0] in ("rclpy", "rosbags")))',
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert probe.returncode == 0 and probe.stdout.strip() == '[]', probe.stdout + probe.stderr


@pytest.mark.parametrize('exe', ['recorder', 'player'])
@pytest.mark.parametrize(
    'delay, signame',
    [(0.0, 'SIGINT'), (0.1, 'SIGTERM'), (0.3, 'SIGINT'), (0.6, 'SIGTERM'), (None, 'SIGINT')],
)
def test_signal_at_any_moment_exits_0(
    ros_process, tmp_path: Path, exe: str, delay, signame: str
) -> None:
    """SIGINT/SIGTERM during imports, start-up or the run: exit 0, no traceback.

    An opened bag is closed.
    """
    from bag_helpers import synthetic_run, write_run_bag

    bag = tmp_path / 'sig'
    if exe == 'recorder':
        args = ['-o', str(bag)]
    else:
        args = [str(write_run_bag(tmp_path / 'src', synthetic_run(duration_s=0.2))), '--loop']
    proc = ros_process('actuator_bag', exe, args)
    if delay is None:
        proc.wait_for_output(
            r'recording \d+ topics' if exe == 'recorder' else 'playing', timeout=30
        )
    else:
        # Delays count from the entry point (it handles SIGTERM from its first line: Python alone
        # does not); the interpreter start and console-script wrapper before it are not this
        # code's.
        wait_for_signal_handler(proc, signal.SIGTERM)
        time.sleep(delay)
    proc.popen.send_signal(getattr(signal, signame))
    assert proc.wait(20) == 0, proc.describe()
    assert 'Traceback' not in proc.stderr + proc.stdout, proc.describe()
    if exe == 'recorder' and bag.exists():
        assert (bag / 'metadata.yaml').is_file(), proc.describe()
