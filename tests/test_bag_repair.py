"""bag_repair rebuilds interrupted bags from what is readable, never touching the original (ROS-free part).

The end-to-end case (recorder killed with SIGKILL mid-run) is in test_bag_record.py.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip('rosbags')

from rosbags.highlevel import AnyReader  # noqa: E402
from rosbags.rosbag2 import Reader  # noqa: E402

from actuator_bag.bag_format import BagWriter, mcap_name, topic_spec  # noqa: E402
from actuator_bag.repair import main, repair_bag  # noqa: E402
from test_bag_support import SOURCE  # noqa: E402

MSGTYPE = 'actuator_msgs/msg/CurrentCommand'


def _digest(path: Path) -> str:
    """SHA-256 of a file."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _interrupted_bag(path: Path, flushed: int, unflushed: int) -> list[bytes]:
    """A bag whose writer flushed ``flushed`` messages and then died (abort: no summary, no metadata.yaml)."""
    store = SOURCE.typestore([MSGTYPE])
    types = store.types
    payloads = []
    writer = BagWriter(path, chunk_size=4096)
    writer.open()
    handle = writer.add_topic(topic_spec('/current_command', MSGTYPE, SOURCE))
    for k in range(flushed + unflushed):
        msg = types[MSGTYPE](
            header=types['std_msgs/msg/Header'](
                stamp=types['builtin_interfaces/msg/Time'](sec=1, nanosec=k), frame_id=''),
            current_a=0.001 * k, safe_stop=False)
        data = bytes(store.serialize_cdr(msg, MSGTYPE))
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
    """Everything flushed is recovered in a new folder; the original file is byte-identical afterwards."""
    bag = tmp_path / 'run'
    payloads = _interrupted_bag(bag, flushed=700, unflushed=50)
    original = _digest(bag / mcap_name(bag))
    with pytest.raises(Exception):
        Reader(bag).open()  # no metadata.yaml: unreadable as a bag before repair
    result = repair_bag(bag, quiet=True)
    assert result.summary.path == tmp_path / 'run_repaired'
    assert _read(result.summary.path) == payloads[:700]
    assert _digest(bag / mcap_name(bag)) == original
    assert sorted(p.name for p in bag.iterdir()) == ['run_0.mcap']
    assert (result.summary.path / 'metadata.yaml').is_file()


@pytest.mark.parametrize('cut', [1, 37, 500, 2000, 6000])
def test_truncated_anywhere_stops_cleanly(tmp_path: Path, cut: int) -> None:
    """Cutting the file at any point loses at most the damaged tail; every recovered message decodes."""
    bag = tmp_path / 'run'
    payloads = _interrupted_bag(bag, flushed=600, unflushed=0)
    mcap = bag / mcap_name(bag)
    size = mcap.stat().st_size
    with open(mcap, 'r+b') as bio:
        bio.truncate(max(size - cut, 200))
    result = repair_bag(bag, tmp_path / 'fixed', quiet=True)
    got = _read(tmp_path / 'fixed')
    assert 0 < len(got) <= 600
    assert got == payloads[:len(got)]
    assert 'truncated' in result.line() or 'without MCAP footer' in result.line()


def test_corrupt_chunk_keeps_what_precedes_it(tmp_path: Path) -> None:
    """A chunk whose bytes were damaged fails its CRC; the scan stops there with the earlier chunks intact."""
    bag = tmp_path / 'run'
    payloads = _interrupted_bag(bag, flushed=600, unflushed=0)
    mcap = bag / mcap_name(bag)
    data = bytearray(mcap.read_bytes())
    middle = len(data) // 2
    data[middle:middle + 64] = bytes(64)
    mcap.write_bytes(bytes(data))
    result = repair_bag(bag, tmp_path / 'fixed', quiet=True)
    got = _read(tmp_path / 'fixed')
    assert 0 < len(got) < 600 and got == payloads[:len(got)]
    assert 'corrupt' in result.line() or 'truncated' in result.line()


def test_complete_bag_repairs_to_same_messages(tmp_path: Path) -> None:
    """Repairing an intact bag gives the same messages and keeps its custom_data."""
    store = SOURCE.typestore([MSGTYPE])
    src = tmp_path / 'ok'
    with BagWriter(src, custom_data={'note': 'kept'}) as writer:
        handle = writer.add_topic(topic_spec('/current_command', MSGTYPE, SOURCE))
        msg = store.types[MSGTYPE](
            header=store.types['std_msgs/msg/Header'](
                stamp=store.types['builtin_interfaces/msg/Time'](sec=1, nanosec=2), frame_id=''),
            current_a=1.0, safe_stop=True)
        for k in range(20):
            writer.write(handle, k, bytes(store.serialize_cdr(msg, MSGTYPE)))
    result = repair_bag(src, tmp_path / 'again', quiet=True)
    assert _read(tmp_path / 'again') == _read(src)
    with Reader(tmp_path / 'again') as reader:
        assert reader.storage.metadata.custom['note'] == 'kept'
    assert result.scans[0].complete and result.scans[0].bytes_lost == 0


def _cli(*args: str) -> subprocess.CompletedProcess:
    """Run bag_repair as a separate process."""
    return subprocess.run(
        [sys.executable, '-m', 'actuator_bag.repair', *args], capture_output=True, text=True, timeout=120,
    )


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


@pytest.mark.parametrize('case', ['missing', 'not_mcap', 'empty_dir', 'output_exists', 'header_only'])
def test_cli_bad_input_is_one_line_error(tmp_path: Path, case: str) -> None:
    """Each kind of bad input gives one line naming the problem and exit code 1, never a traceback."""
    target = tmp_path / 'bag'
    expect = {
        'missing': 'does not exist', 'not_mcap': 'not an MCAP file', 'empty_dir': 'no .mcap file',
        'output_exists': 'exists already', 'header_only': 'nothing recoverable',
    }[case]
    if case == 'not_mcap':
        target.mkdir()
        (target / 'bag_0.mcap').write_text('hello, this is text\n')
    elif case == 'empty_dir':
        target.mkdir()
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
    assert len(lines) == 1 and lines[0].startswith('bag_repair: error: ') and expect in lines[0], proc.stderr


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
