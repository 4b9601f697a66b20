# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""No bag tool writes inside or over a source bag.

Output locations are refused before any work; a full disk is one clean error that leaves a
repairable bag (BagWriter) or nothing half-written (bag_repair). ROS-free.

The full disk is real: the test hook ACTUATOR_BAG_TEST_FULL_AFTER_BYTES=N (actuator_bag.datafile)
sends the bytes beyond N of a data file to /dev/full, so the error is the kernel's ENOSPC.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader

from actuator_bag.bag_format import BagWriter, mcap_name
from actuator_bag.datafile import FULL_AFTER_ENV
from actuator_bag.errors import BagIOError
from actuator_bag.repair import repair_bag
from bag_helpers import add_command_topic, command_cdr, synthetic_run, write_run_bag


def _tree(root: Path) -> dict[str, str]:
    """Every file under root (relative path -> SHA-256), to show a folder was not touched."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob('*'))
        if p.is_file()
    }


def _run(module: str, *args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """Run a bag tool (python -m <module>, ``analyze`` the analysis) as a separate process."""
    module = 'actuator_analysis.cli' if module == 'analyze' else f'actuator_bag.{module}'
    return subprocess.run(
        [sys.executable, '-m', module, *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )


def _one_error(proc: subprocess.CompletedProcess, prog: str, expect: str) -> None:
    """Check that the process printed exactly one error line with ``expect``, and no traceback."""
    assert 'Traceback' not in proc.stderr, proc.stderr
    lines = [x for x in proc.stderr.splitlines() if not x.startswith(f'{prog} ')]
    assert len(lines) == 1 and lines[0].startswith(f'{prog}: error: ') and expect in lines[0], (
        proc.stderr
    )


@pytest.fixture
def bag(run_bag) -> Path:
    """Return the path of the session's synthetic run bag (conftest.run_bag)."""
    return run_bag[0]


def _interrupted(path: Path, count: int = 300) -> Path:
    """Write an interrupted bag of ``count`` messages in small chunks.

    Interrupted: no summary, no metadata.yaml.
    """
    writer = BagWriter(path, chunk_size=4096)
    writer.open()
    handle = add_command_topic(writer)
    for k in range(count):
        writer.write(handle, 1000 + k, command_cdr(k, 0.1))
    writer.flush()
    writer.abort()
    return path


# ------------------------------------------------------------------------------ bag_analyze
@pytest.mark.slow
@pytest.mark.parametrize(
    'case',
    [
        'json_inside',
        'json_is_mcap',
        'json_links_to_input',
        'out_inside',
        'out_is_bag',
        'out_figure_links_to_input',
        'json_folder_missing',
        'json_under_a_file',
    ],
)
def test_analyze_refuses_output_locations_before_work(
    bag: Path, tmp_path: Path, case: str
) -> None:
    """bag_analyze refuses an output inside/over an input bag (links too) or unwritable.

    One line, exit 2, no work.
    """
    before = _tree(bag)
    mcap = bag / mcap_name(bag)
    link = tmp_path / 'link.json'
    if case in ('json_links_to_input', 'out_figure_links_to_input'):
        link.symlink_to(bag / 'metadata.yaml')
    (tmp_path / 'afile').write_text('x')
    (tmp_path / 'figs').mkdir()
    if case == 'out_figure_links_to_input':
        os.link(mcap, tmp_path / 'figs' / 'position.png')
    option, target, expect = {
        'json_inside': ('--json', bag / 'report.json', 'inside the source bag'),
        'json_is_mcap': ('--json', mcap, 'would overwrite the input file'),
        'json_links_to_input': ('--json', link, 'would overwrite the input file'),
        'out_inside': ('--out', bag / 'figures', 'inside the source bag'),
        'out_is_bag': ('--out', bag, 'inside the source bag'),
        'out_figure_links_to_input': (
            '--out',
            tmp_path / 'figs',
            'would overwrite the input file',
        ),
        'json_folder_missing': ('--json', tmp_path / 'nowhere' / 'r.json', 'does not exist'),
        'json_under_a_file': (
            '--json',
            tmp_path / 'afile' / 'r.json',
            'does not exist or is not a folder',
        ),
    }[case]
    proc = _run('analyze', str(bag), option, str(target))
    assert proc.returncode == 2, proc.stderr
    _one_error(proc, 'bag_analyze', expect)
    assert proc.stdout == ''  # refused before the analysis ran
    assert _tree(bag) == before


@pytest.mark.slow
def test_analyze_writes_next_to_a_bag(bag: Path, tmp_path: Path) -> None:
    """Outputs beside the bag (a sibling folder, a file in the bag's parent) are accepted."""
    proc = _run(
        'analyze',
        '-q',
        str(bag),
        '--json',
        str(tmp_path / 'r.json'),
        '--out',
        str(tmp_path / 'figs'),
    )
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / 'r.json').is_file() and (tmp_path / 'figs' / 'position.png').is_file()


# ------------------------------------------------------------------------------- bag_repair
@pytest.mark.slow
@pytest.mark.parametrize(
    'case', ['out_inside', 'out_is_bag', 'json_inside', 'out_under_a_file', 'json_is_mcap']
)
def test_repair_refuses_output_locations_before_work(tmp_path: Path, case: str) -> None:
    """bag_repair refuses -o/--json inside or over the bag, or an -o it cannot create.

    Exit 2, no work, nothing made.
    """
    src = _interrupted(tmp_path / 'run')
    before = _tree(src)
    (tmp_path / 'afile').write_text('x')
    args, expect = {
        'out_inside': (['-o', str(src / 'fixed')], 'inside the source bag'),
        'out_is_bag': (['-o', str(src)], 'inside the source bag'),
        'json_inside': (['--json', str(src / 'r.json')], 'inside the source bag'),
        'out_under_a_file': (
            ['-o', str(tmp_path / 'afile' / 'fixed')],
            'is not a writable folder',
        ),
        'json_is_mcap': (['--json', str(src / mcap_name(src))], 'would overwrite the input file'),
    }[case]
    proc = _run('repair', str(src), *args)
    assert proc.returncode == 2, proc.stderr
    _one_error(proc, 'bag_repair', expect)
    assert '%' not in proc.stderr and proc.stdout == ''
    assert _tree(src) == before
    assert not (tmp_path / 'run_repaired').exists()


@pytest.mark.slow
def test_repair_report_may_go_into_the_new_output(tmp_path: Path) -> None:
    """--json inside the -o folder repair creates is accepted.

    That folder is new, not a source.
    """
    src = _interrupted(tmp_path / 'run')
    proc = _run(
        'repair',
        '-q',
        str(src),
        '-o',
        str(tmp_path / 'fixed'),
        '--json',
        str(tmp_path / 'fixed' / 'r.json'),
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads((tmp_path / 'fixed' / 'r.json').read_text())['messages_lost'] == 0


@pytest.mark.slow
def test_repair_refuses_existing_non_empty_output(tmp_path: Path) -> None:
    """An -o folder that exists and holds files is refused (its files stay as they were)."""
    src = _interrupted(tmp_path / 'run')
    out = tmp_path / 'busy'
    out.mkdir()
    (out / 'keep.txt').write_text('mine')
    proc = _run('repair', str(src), '-o', str(out))
    assert proc.returncode == 1
    _one_error(proc, 'bag_repair', 'exists already and is not empty')
    assert _tree(out) == {'keep.txt': hashlib.sha256(b'mine').hexdigest()}


def test_repair_of_a_file_in_its_bag_folder_writes_beside_the_folder(tmp_path: Path) -> None:
    """bag_repair bags/run/run_0.mcap puts run_repaired next to bags/run.

    Not inside the source bag.
    """
    src = _interrupted(tmp_path / 'run')
    result = repair_bag(src / mcap_name(src), quiet=True)
    assert result.summary.path == tmp_path / 'run_repaired'
    assert sorted(p.name for p in src.iterdir()) == ['run_0.mcap']


# -------------------------------------------------------------------------------- full disk
@pytest.mark.parametrize('limit', [5000, 12345, 20000])
def test_writer_full_disk_is_one_error_and_leaves_a_repairable_file(
    tmp_path: Path, limit: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Disk full mid-write: one BagIOError (ENOSPC), file cut to a record end.

    Repair recovers exactly `durable`.
    """
    monkeypatch.setenv(FULL_AFTER_ENV, str(limit))
    writer = BagWriter(tmp_path / 'full', chunk_size=4096)
    writer.open()
    handle = add_command_topic(writer)
    with pytest.raises(BagIOError) as err:
        for k in range(100_000):
            writer.write(handle, 1000 + k, command_cdr(k, 0.5))
    assert err.value.errno == errno.ENOSPC and 'No space left on device' in str(err.value)
    assert not writer.is_open and 0 < writer.durable <= sum(writer.counts)
    mcap = tmp_path / 'full' / mcap_name(tmp_path / 'full')
    data = mcap.read_bytes()
    assert len(data) <= limit
    pos = 8
    while pos < len(data):  # the file ends exactly on a record boundary
        pos += 9 + struct.unpack_from('<BQ', data, pos)[1]
    assert pos == len(data)
    monkeypatch.delenv(FULL_AFTER_ENV)
    result = repair_bag(tmp_path / 'full', tmp_path / 'fixed', quiet=True)
    assert result.summary.message_count == writer.durable and result.bytes_lost == 0


def test_writer_that_cannot_start_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A disk full from the first byte: open() raises BagIOError.

    It removes the folders it created.
    """
    monkeypatch.setenv(FULL_AFTER_ENV, '0')
    with pytest.raises(BagIOError, match='No space left on device'):
        BagWriter(tmp_path / 'a' / 'b' / 'bag').open()
    assert not (tmp_path / 'a').exists()


@pytest.mark.slow
@pytest.mark.parametrize('limit', ['0', '3000', '30000'])
def test_repair_onto_a_full_disk(tmp_path: Path, limit: str) -> None:
    """bag_repair onto a full disk: exit 1, one ENOSPC line, no traceback.

    None of its output (or parents) is left.
    """
    src = write_run_bag(tmp_path / 'run', synthetic_run(duration_s=0.5))
    (src / 'metadata.yaml').unlink()
    before = _tree(src)
    env = {**os.environ, FULL_AFTER_ENV: limit}
    proc = _run(
        'repair', '-q', str(src), '-o', str(tmp_path / 'new' / 'deeper' / 'fixed'), env=env
    )
    assert proc.returncode == 1, proc.stderr
    _one_error(proc, 'bag_repair', 'No space left on device (ENOSPC)')
    assert not (tmp_path / 'new').exists()
    assert _tree(src) == before


def test_repaired_bag_after_a_full_disk_reads_back(tmp_path: Path) -> None:
    """The repaired copy of a bag whose recording hit a full disk is a normal bag.

    rosbags reads every message.
    """
    src = _interrupted(tmp_path / 'run', count=500)
    result = repair_bag(src, tmp_path / 'fixed', quiet=True)
    with AnyReader([tmp_path / 'fixed']) as reader:
        assert sum(1 for _ in reader.messages()) == result.summary.message_count == 500
