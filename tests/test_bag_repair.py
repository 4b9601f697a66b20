# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""bag_repair rebuilds interrupted bags from what is readable, never touching the original.

This is the ROS-free part. The end-to-end case (recorder killed with SIGKILL mid-run) is in
test_bag_record.py.
"""

from __future__ import annotations

import hashlib
import json
import os
import random
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader

from actuator_bag.bag_format import BagWriter, mcap_name
from actuator_bag.errors import RepairError
from actuator_bag.repair import main, repair_bag
from bag_helpers import add_command_topic, command_cdr


def _digest(path: Path) -> str:
    """SHA-256 of a file."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _interrupted_bag(path: Path, flushed: int, unflushed: int) -> list[bytes]:
    """Write a bag whose writer flushed ``flushed`` messages and then died.

    Abort: no summary, no metadata.yaml.
    """
    payloads = []
    writer = BagWriter(path, chunk_size=4096)
    writer.open()
    handle = add_command_topic(writer)
    for k in range(flushed + unflushed):
        data = command_cdr(k, 0.001 * k)
        payloads.append(data)
        writer.write(handle, 10_000 + k, data)
        if k + 1 == flushed:
            writer.flush()
    writer.abort()
    return payloads


def _read(path: Path) -> list[bytes]:
    """Every message of a bag, decoded through AnyReader (hash check) and returned as raw bytes."""
    with AnyReader([path]) as reader:
        out = []
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            out.append(bytes(raw))
    return out


def test_repairs_interrupted_bag_without_touching_it(tmp_path: Path) -> None:
    """Everything flushed is recovered in a new folder.

    The original file is byte-identical afterwards.
    """
    bag = tmp_path / 'run'
    payloads = _interrupted_bag(bag, flushed=700, unflushed=50)
    original = _digest(bag / mcap_name(bag))
    with pytest.raises(FileNotFoundError, match='metadata'):
        Reader(bag).open()  # no metadata.yaml: unreadable as a bag before repair
    result = repair_bag(bag, quiet=True)
    assert result.summary.path == tmp_path / 'run_repaired'
    assert _read(result.summary.path) == payloads[:700]
    assert _digest(bag / mcap_name(bag)) == original
    assert sorted(p.name for p in bag.iterdir()) == ['run_0.mcap']
    assert (result.summary.path / 'metadata.yaml').is_file()


@pytest.mark.parametrize('cut', [1, 37, 500, 2000, 6000])
def test_truncated_anywhere_stops_cleanly(tmp_path: Path, cut: int) -> None:
    """Cutting the file at any point loses at most the damaged tail.

    Every recovered message decodes.
    """
    bag = tmp_path / 'run'
    payloads = _interrupted_bag(bag, flushed=600, unflushed=0)
    mcap = bag / mcap_name(bag)
    size = mcap.stat().st_size
    with open(mcap, 'r+b') as bio:
        bio.truncate(max(size - cut, 200))
    result = repair_bag(bag, tmp_path / 'fixed', quiet=True)
    got = _read(tmp_path / 'fixed')
    assert 0 < len(got) <= 600
    assert got == payloads[: len(got)]
    assert 'truncated' in result.line() or 'without MCAP footer' in result.line()


def test_corrupt_chunk_keeps_what_precedes_it(tmp_path: Path) -> None:
    """A chunk whose bytes were damaged fails its CRC.

    The earlier chunks are intact, and so are the later ones.
    """
    bag = tmp_path / 'run'
    payloads = _interrupted_bag(bag, flushed=600, unflushed=0)
    mcap = bag / mcap_name(bag)
    data = bytearray(mcap.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 64] = bytes(64)
    mcap.write_bytes(bytes(data))
    result = repair_bag(bag, tmp_path / 'fixed', quiet=True)
    got = _read(tmp_path / 'fixed')
    assert 0 < len(got) < 600
    first_missing = next(i for i, (x, y) in enumerate(zip(got, payloads)) if x != y)
    resumed = first_missing + 600 - len(got)
    # Every chunk before the damage is intact, and (since the resync) every chunk after it too.
    assert first_missing > 0 and got == payloads[:first_missing] + payloads[resumed:]
    assert 'corrupt' in result.line() or 'truncated' in result.line()


def test_complete_bag_repairs_to_same_messages(tmp_path: Path) -> None:
    """Repairing an intact bag gives the same messages and keeps its custom_data."""
    src = tmp_path / 'ok'
    with BagWriter(src, custom_data={'note': 'kept'}) as writer:
        handle = add_command_topic(writer)
        for k in range(20):
            writer.write(handle, k, command_cdr(2, 1.0, safe_stop=True))
    result = repair_bag(src, tmp_path / 'again', quiet=True)
    assert _read(tmp_path / 'again') == _read(src)
    with Reader(tmp_path / 'again') as reader:
        assert reader.storage.metadata.custom['note'] == 'kept'
    assert result.scans[0].complete and result.scans[0].bytes_lost == 0


def _cli(*args: str) -> subprocess.CompletedProcess:
    """Run bag_repair as a separate process."""
    return subprocess.run(
        [sys.executable, '-m', 'actuator_bag.repair', *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.mark.slow
def test_cli_reports_progress_and_result(tmp_path: Path) -> None:
    """Progress lines go to stderr, a one-line result to stdout, exit code 0."""
    bag = tmp_path / 'run'
    _interrupted_bag(bag, flushed=300, unflushed=0)
    proc = _cli(str(bag), '--json', str(tmp_path / 'r.json'))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith('repaired ') and proc.stdout.count('\n') == 1
    assert '300 messages' in proc.stdout
    assert '100 %' in proc.stderr
    assert (tmp_path / 'r.json').is_file()


@pytest.mark.slow
@pytest.mark.parametrize(
    'case', ['missing', 'not_mcap', 'empty_dir', 'output_exists', 'header_only', 'empty_file']
)
def test_cli_bad_input_is_one_line_error(tmp_path: Path, case: str) -> None:
    """Each kind of bad input gives one line naming the problem, exit code 1, never a traceback."""
    target = tmp_path / 'bag'
    expect = {
        'missing': 'does not exist',
        'not_mcap': 'not an MCAP file',
        'empty_dir': 'no .mcap file',
        'output_exists': 'exists already',
        'header_only': 'nothing recoverable',
        'empty_file': 'not an MCAP file',
    }[case]
    if case == 'not_mcap':
        target.mkdir()
        (target / 'bag_0.mcap').write_text('hello, this is text\n')
    elif case == 'empty_dir':
        target.mkdir()
    elif case == 'empty_file':
        target.mkdir()
        (target / 'bag_0.mcap').write_bytes(b'')
    elif case == 'output_exists':
        _interrupted_bag(target, flushed=10, unflushed=0)
        (tmp_path / 'bag_repaired').mkdir()
    elif case == 'header_only':
        _interrupted_bag(target, flushed=10, unflushed=0)
        mcap = target / mcap_name(target)
        with open(mcap, 'r+b') as bio:
            bio.truncate(40)
    proc = _cli(str(target))
    assert proc.returncode == 1
    assert 'Traceback' not in proc.stderr
    lines = [x for x in proc.stderr.splitlines() if not x.startswith('bag_repair ')]
    assert len(lines) == 1 and lines[0].startswith('bag_repair: error: ') and expect in lines[0], (
        proc.stderr
    )


def test_help() -> None:
    """--help answers and exits 0."""
    with pytest.raises(SystemExit) as exc:
        main(['--help'])
    assert exc.value.code == 0


def test_original_folder_not_modified_on_failure(tmp_path: Path) -> None:
    """A failing repair leaves the source folder exactly as it was."""
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'x_0.mcap').write_bytes(b'\x89MCAP0\r\n' + b'\x01' + (10**9).to_bytes(8, 'little'))
    before = {p.name: _digest(p) for p in bag.iterdir()}
    assert main([str(bag), '-q']) == 1
    assert {p.name: _digest(p) for p in bag.iterdir()} == before
    assert not (tmp_path / 'bag_repaired').exists()
    shutil.rmtree(bag)
    assert not os.path.exists(bag)


# ------------------------------------------------------------- resynchronisation after damage
CHUNK, MESSAGE_INDEX = 0x06, 0x07


def _records(path: Path) -> list[tuple[int, int, int]]:
    """(opcode, start, end) of every top-level record of an intact MCAP file, in file order."""
    data = path.read_bytes()
    out, pos = [], 8
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from('<BQ', data, pos)
        out.append((opcode, pos, pos + 9 + length))
        pos += 9 + length
    return out


def _chunk_messages(path: Path) -> list[int]:
    """Messages per chunk, in file order, from the message index records that follow each chunk."""
    data = path.read_bytes()
    counts: list[int] = []
    for opcode, start, _ in _records(path):
        if opcode == CHUNK:
            counts.append(0)
        elif opcode == MESSAGE_INDEX:
            counts[-1] += struct.unpack_from('<I', data, start + 9 + 2)[0] // 16
    return counts


def _damaged(
    tmp_path: Path, damage
) -> tuple[Path, list[bytes], list[tuple[int, int, int]], list[int]]:
    """Make an interrupted bag of 6+ chunks damaged by damage(data, chunks).

    Return it, its payloads, records, messages per chunk.
    """
    bag = tmp_path / 'run'
    payloads = _interrupted_bag(bag, flushed=600, unflushed=0)
    mcap = bag / mcap_name(bag)
    records, per_chunk = _records(mcap), _chunk_messages(mcap)
    assert len(per_chunk) >= 6 and sum(per_chunk) == 600
    data = bytearray(mcap.read_bytes())
    damage(data, [r for r in records if r[0] == CHUNK])
    mcap.write_bytes(bytes(data))
    return bag, payloads, records, per_chunk


@pytest.mark.slow
def test_resyncs_after_a_chunk_failing_its_crc(tmp_path: Path) -> None:
    """Chunk 3 fails its CRC: exactly it is skipped, later chunks recovered.

    Its range and message count are reported.
    """

    def damage(data: bytearray, chunks: list) -> None:
        _, start, end = chunks[2]
        middle = (start + end) // 2
        data[middle : middle + 16] = bytes(b ^ 0x5A for b in data[middle : middle + 16])

    bag, payloads, records, per_chunk = _damaged(tmp_path, damage)
    _, start, end = [r for r in records if r[0] == CHUNK][2]
    before = sum(per_chunk[:2])
    result = repair_bag(bag, tmp_path / 'fixed', quiet=True)
    assert _read(tmp_path / 'fixed') == payloads[:before] + payloads[before + per_chunk[2] :]
    scan = result.scans[0]
    assert [(x.start, x.end, x.messages) for x in scan.losses] == [(start, end, per_chunk[2])]
    assert 'CRC' in scan.losses[0].reason.upper() and result.messages_lost == per_chunk[2]
    assert f'{end - start} bytes not recoverable, {per_chunk[2]} messages lost' in result.line()
    assert f'bytes {start}-{end}' in result.line()
    proc = _cli(str(bag), '-o', str(tmp_path / 'cli'), '--json', str(tmp_path / 'r.json'), '-q')
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((tmp_path / 'r.json').read_text())
    assert doc['bytes_lost'] == end - start and doc['messages_lost'] == per_chunk[2]
    loss = doc['scans'][0]['losses'][0]
    assert (loss['start'], loss['end'], loss['bytes'], loss['messages']) == (
        start,
        end,
        end - start,
        per_chunk[2],
    )


def test_resyncs_after_garbage_over_a_record_header(tmp_path: Path) -> None:
    """Garbage over chunk 4's header: resync at the next plausible record.

    Later chunks are recovered; the count is unknown.
    """
    rng = random.Random(4)

    def damage(data: bytearray, chunks: list) -> None:
        start = chunks[3][1]
        data[start : start + 48] = bytes(rng.randrange(256) for _ in range(48))

    bag, payloads, records, per_chunk = _damaged(tmp_path, damage)
    chunk_pos = [i for i, r in enumerate(records) if r[0] == CHUNK][3]
    start, resume = (
        records[chunk_pos][1],
        records[chunk_pos + 1][1],
    )  # its first message index record
    before = sum(per_chunk[:3])
    result = repair_bag(bag, tmp_path / 'fixed', quiet=True)
    assert _read(tmp_path / 'fixed') == payloads[:before] + payloads[before + per_chunk[3] :]
    assert [(x.start, x.end, x.messages) for x in result.scans[0].losses] == [
        (start, resume, None)
    ]
    assert result.messages_lost is None and 'an unknown number of messages lost' in result.line()
    assert result.scans[0].as_dict()['losses'][0]['messages'] == 'unknown'


def test_garbage_inserted_between_chunks_loses_no_message(tmp_path: Path) -> None:
    """1000 random bytes inserted between two chunks: all 600 messages recovered.

    Exactly that range is reported.
    """
    rng = random.Random(7)
    inserted: list[int] = []

    def damage(data: bytearray, chunks: list) -> None:
        inserted.append(chunks[5][1])
        data[chunks[5][1] : chunks[5][1]] = bytes(rng.randrange(256) for _ in range(1000))

    bag, payloads, _, _ = _damaged(tmp_path, damage)
    result = repair_bag(bag, tmp_path / 'fixed', quiet=True)
    assert _read(tmp_path / 'fixed') == payloads
    assert [(x.start, x.end) for x in result.scans[0].losses] == [
        (inserted[0], inserted[0] + 1000)
    ]
    assert result.bytes_lost == 1000


def test_two_damaged_places_are_both_reported(tmp_path: Path) -> None:
    """A CRC-failing chunk and a damaged header later: both ranges reported.

    The counted messages are a lower bound.
    """

    def damage(data: bytearray, chunks: list) -> None:
        _, start, end = chunks[1]
        data[(start + end) // 2] ^= 0xFF
        data[chunks[4][1] : chunks[4][1] + 30] = b'\xff' * 30

    bag, payloads, records, per_chunk = _damaged(tmp_path, damage)
    chunks = [r for r in records if r[0] == CHUNK]
    result = repair_bag(bag, tmp_path / 'fixed', quiet=True)
    losses = result.scans[0].losses
    assert [(x.start, x.messages) for x in losses] == [
        (chunks[1][1], per_chunk[1]),
        (chunks[4][1], None),
    ]
    assert losses[0].end == chunks[1][2]
    assert f'at least {per_chunk[1]} messages lost' in result.line()
    assert (
        result.as_dict()['messages_lost'] == 'unknown'
        and result.as_dict()['messages_lost_counted'] == per_chunk[1]
    )
    first, second = sum(per_chunk[:1]), sum(per_chunk[:4])
    assert _read(tmp_path / 'fixed') == (
        payloads[:first]
        + payloads[first + per_chunk[1] : second]
        + payloads[second + per_chunk[4] :]
    )


def test_complete_bag_with_a_corrupt_chunk_reaches_its_end(tmp_path: Path) -> None:
    """A closed bag (summary, footer) with one damaged chunk.

    The scan goes on to the end of the data section.
    """
    src = tmp_path / 'ok'
    with BagWriter(src, chunk_size=2048) as writer:
        handle = add_command_topic(writer)
        for k in range(400):
            writer.write(handle, k, command_cdr(k, float(k)))
    mcap = src / mcap_name(src)
    per_chunk = _chunk_messages(mcap)
    chunks = [r for r in _records(mcap) if r[0] == CHUNK]
    data = bytearray(mcap.read_bytes())
    middle = (chunks[1][1] + chunks[1][2]) // 2
    data[middle] ^= 0xFF
    mcap.write_bytes(bytes(data))
    result = repair_bag(src, tmp_path / 'again', quiet=True)
    assert result.scans[0].complete and result.scans[0].stop_reason == 'end of data section'
    assert len(_read(tmp_path / 'again')) == 400 - per_chunk[1]
    assert result.messages_lost == per_chunk[1]


def test_adjacent_corrupt_chunks_are_each_counted(tmp_path: Path) -> None:
    """Chunks 2 and 3 both fail their CRC: two exact ranges, each with its own message count.

    The rest is recovered.
    """

    def damage(data: bytearray, chunks: list) -> None:
        for _, start, end in chunks[2:4]:
            data[(start + end) // 2] ^= 0xFF

    bag, payloads, records, per_chunk = _damaged(tmp_path, damage)
    chunks = [r for r in records if r[0] == CHUNK]
    result = repair_bag(bag, tmp_path / 'fixed', quiet=True)
    assert [(x.start, x.end, x.messages) for x in result.scans[0].losses] == [
        (chunks[2][1], chunks[2][2], per_chunk[2]),
        (chunks[3][1], chunks[3][2], per_chunk[3]),
    ]
    assert result.messages_lost == per_chunk[2] + per_chunk[3]
    before = sum(per_chunk[:2])
    assert (
        _read(tmp_path / 'fixed')
        == payloads[:before] + payloads[before + per_chunk[2] + per_chunk[3] :]
    )


def test_closed_bag_with_its_first_chunk_lost_keeps_the_rest(tmp_path: Path) -> None:
    """Closed bag, first chunk (schema, channel) corrupt: definitions come from the summary.

    Later chunks are recovered.
    """
    src = tmp_path / 'ok'
    payloads = []
    with BagWriter(src, chunk_size=2048) as writer:
        handle = add_command_topic(writer)
        for k in range(300):
            payloads.append(command_cdr(k, float(k)))
            writer.write(handle, k, payloads[-1])
    mcap = src / mcap_name(src)
    per_chunk = _chunk_messages(mcap)
    first = [r for r in _records(mcap) if r[0] == CHUNK][0]
    data = bytearray(mcap.read_bytes())
    data[(first[1] + first[2]) // 2] ^= 0xFF
    mcap.write_bytes(bytes(data))
    result = repair_bag(src, tmp_path / 'again', quiet=True)
    assert _read(tmp_path / 'again') == payloads[per_chunk[0] :]
    assert result.scans[0].without_channel == 0 and result.messages_lost == per_chunk[0]


def test_lost_channel_definition_is_reported(tmp_path: Path) -> None:
    """Interrupted bag, chunk defining the channel lost.

    Later messages are counted as without channel, not hidden.
    """

    def damage(data: bytearray, chunks: list) -> None:
        _, start, end = chunks[0]
        data[(start + end) // 2] ^= 0xFF

    bag, _, _, per_chunk = _damaged(tmp_path, damage)
    with pytest.raises(RepairError, match='nothing recoverable') as err:
        repair_bag(bag, tmp_path / 'fixed', quiet=True)
    assert (
        f'{600 - per_chunk[0]} messages of intact chunks whose channel was defined in a lost part'
        in str(err.value)
    )
    assert not (tmp_path / 'fixed').exists()


def test_a_schema_whose_text_is_not_utf8_is_refused_in_one_line() -> None:
    """A damaged schema text ends the repair with its reason, not a UnicodeDecodeError."""
    from mcap.records import Channel, Schema

    from actuator_bag.repair import _topic_from

    schema = Schema(id=1, name='sensor_msgs/msg/JointState', encoding='ros2msg', data=b'\xff\xfe')
    channel = Channel(
        id=1, schema_id=1, topic='/joint_states', message_encoding='cdr', metadata={}
    )
    with pytest.raises(RepairError, match=r'/joint_states: the text of its schema .* not UTF-8'):
        _topic_from(channel, schema)
