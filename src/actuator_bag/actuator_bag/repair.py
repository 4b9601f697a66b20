"""``bag_repair``: rebuild a bag whose recorder died (no MCAP summary or footer, no metadata.yaml).

The MCAP files of the bag are scanned linearly, record by record. Schemas, channels and
messages are taken from every complete, CRC-valid chunk; the scan stops cleanly at the
first truncated or corrupt record (the tail a killed process left half-written) or at
the end of the data section. What was read is written to a NEW bag folder (default
``<bag>_repaired``) with a fresh MCAP index and metadata.yaml; the original files are only
read, never modified.
"""

from __future__ import annotations

import argparse
import json
import os
import struct
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import Any, BinaryIO, Callable, Iterator, Optional, Sequence, Union

import yaml
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Header, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, breakup_chunk
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import TypesysError

from .bag_format import BagSummary, BagWriter, TopicSpec, qos_from_yaml
from .errors import BagWriteError, RepairError, run_cli
from .progress import Progress

MCAP_MAGIC = b'\x89MCAP0\r\n'
_RECORD_HEADER = struct.Struct('<BQ')

Record = Union[Schema, Channel, Message, Metadata, Header]


@dataclass
class ScanReport:
    """Outcome of scanning one MCAP file: where and why it stopped, what it found."""

    path: Path
    file_size: int
    bytes_read: int = 0
    complete: bool = False
    stop_reason: str = ''
    chunks: int = 0
    messages: int = 0
    profile: str = ''
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)

    @property
    def bytes_lost(self) -> int:
        """Bytes of the data section after the last complete record (not recoverable)."""
        return 0 if self.complete else self.file_size - self.bytes_read


def _read_exact(bio: BinaryIO, size: int) -> bytes:
    """Read size bytes or fewer at end of file."""
    return bio.read(size)


def scan_mcap(
    path: Path, report: ScanReport, on_progress: Optional[Callable[[int], None]] = None
) -> Iterator[Record]:
    """Yield the schemas, channels, messages and metadata of an MCAP file in file order, stopping at damage.

    ``report`` is filled in as the scan goes; it says where and why the scan stopped.
    """
    with open(path, 'rb') as bio:
        if _read_exact(bio, 8) != MCAP_MAGIC:
            raise RepairError(f'{path} is not an MCAP file (bad magic)')
        pos = 8
        report.bytes_read = pos
        while True:
            head = _read_exact(bio, _RECORD_HEADER.size)
            if not head:
                report.stop_reason = f'file ends at byte {pos} without MCAP footer'
                return
            if len(head) < _RECORD_HEADER.size:
                report.stop_reason = f'truncated record header at byte {pos}'
                return
            opcode, length = _RECORD_HEADER.unpack(head)
            if length > report.file_size - pos - _RECORD_HEADER.size:
                name = Opcode(opcode).name if opcode in Opcode._value2member_map_ else f'0x{opcode:02x}'
                report.stop_reason = f'truncated {name} record at byte {pos}'
                return
            body = _read_exact(bio, length)
            stream = ReadDataStream(BytesIO(body))
            try:
                if opcode == Opcode.HEADER:
                    report.profile = Header.read(stream).profile
                elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE, Opcode.METADATA):
                    yield _plain_record(opcode, stream, length, report)
                elif opcode == Opcode.CHUNK:
                    chunk = Chunk.read(stream)
                    records = breakup_chunk(chunk, validate_crc=True)
                    report.chunks += 1
                    for record in records:
                        if isinstance(record, Message):
                            report.messages += 1
                        if isinstance(record, (Schema, Channel, Message)):
                            yield record
                elif opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    report.complete = True
                    report.stop_reason = 'end of data section'
                    report.bytes_read = pos + _RECORD_HEADER.size + length
                    return
            except (McapError, CRCValidationError, ValueError, struct.error, UnicodeDecodeError) as err:
                report.stop_reason = f'corrupt record at byte {pos} ({err})'
                return
            pos += _RECORD_HEADER.size + length
            report.bytes_read = pos
            if on_progress is not None:
                on_progress(pos)


def _plain_record(opcode: int, stream: ReadDataStream, length: int, report: ScanReport) -> Record:
    """Decode one record found outside a chunk."""
    if opcode == Opcode.SCHEMA:
        return Schema.read(stream)
    if opcode == Opcode.CHANNEL:
        return Channel.read(stream)
    if opcode == Opcode.METADATA:
        record = Metadata.read(stream)
        report.metadata[record.name] = dict(record.metadata)
        return record
    report.messages += 1
    return Message.read(stream, length)


def mcap_files(bag: Path) -> list[Path]:
    """The MCAP files of a bag folder (or the file itself), in recording order."""
    if bag.is_file():
        return [bag]
    if not bag.is_dir():
        raise RepairError(f'{bag} does not exist')
    files = sorted(bag.glob('*.mcap'), key=lambda p: (len(p.name), p.name))
    if not files:
        raise RepairError(f'{bag} holds no .mcap file, so it is not an MCAP bag')
    return files


def default_output(bag: Path) -> Path:
    """``<bag>_repaired`` next to the bag folder (or next to a single .mcap file, by its stem)."""
    base = bag.parent / (bag.stem if bag.is_file() else bag.name)
    return base.with_name(base.name + '_repaired')


def _type_hash(schema: Schema) -> str:
    """RIHS01 hash computed from a schema's ros2msg text ('' if it cannot be parsed)."""
    if schema.encoding != 'ros2msg':
        return ''
    try:
        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(schema.data.decode('utf-8'), schema.name))
        return store.hash_rihs01(schema.name)
    except (TypesysError, UnicodeDecodeError, KeyError, ValueError):
        return ''


def _topic_from(channel: Channel, schema: Optional[Schema]) -> TopicSpec:
    """TopicSpec from an MCAP channel and its schema (QoS and hash from the channel metadata)."""
    if schema is None:
        raise RepairError(f'channel {channel.topic} has no schema; cannot rebuild it')
    try:
        qos = qos_from_yaml(channel.metadata.get('offered_qos_profiles', ''))
    except (yaml.YAMLError, KeyError, TypeError, ValueError, BagWriteError):
        qos = ()
    return TopicSpec(
        name=channel.topic,
        msgtype=schema.name,
        definition=schema.data.decode('utf-8'),
        type_hash=channel.metadata.get('topic_type_hash') or _type_hash(schema),
        qos=qos,
        serialization_format=channel.message_encoding,
        definition_encoding=schema.encoding,
    )


def _recorded_custom_data(scans: Sequence[ScanReport]) -> dict[str, str]:
    """custom_data of the original bag, when a file still holds its rosbag2 metadata record."""
    for scan in scans:
        text = scan.metadata.get('rosbag2', {}).get('serialized_metadata', '')
        try:
            info = yaml.safe_load(text) if text else None
        except yaml.YAMLError:
            continue
        if isinstance(info, dict) and isinstance(info.get('custom_data'), dict):
            return {str(k): str(v) for k, v in info['custom_data'].items()}
    return {}


@dataclass
class RepairResult:
    """Repaired bag summary plus the per-file scan reports."""

    summary: BagSummary
    scans: list[ScanReport]

    def line(self) -> str:
        """One-line human summary."""
        lost = sum(s.bytes_lost for s in self.scans)
        how = '; '.join(f'{s.path.name}: {s.stop_reason}' for s in self.scans)
        return f'repaired {self.summary.line()}; {how}; {lost} bytes not recoverable'


def repair_bag(
    bag: Union[str, os.PathLike], out: Union[str, os.PathLike, None] = None, *, quiet: bool = False
) -> RepairResult:
    """Scan the bag's MCAP files and write what is readable to the new bag folder ``out``."""
    bag = Path(bag)
    files = mcap_files(bag)
    out = Path(out) if out is not None else default_output(bag)
    if out.exists():
        raise RepairError(f'{out} exists already, not overwriting')
    if out.resolve() == bag.resolve():
        raise RepairError('the repaired bag must go to a new folder')
    total = sum(p.stat().st_size for p in files)
    progress = Progress(f'bag_repair {bag.name}', total, unit='bytes', enabled=not quiet)
    writer: Optional[BagWriter] = None
    scans: list[ScanReport] = []
    done = 0
    try:
        for path in files:
            report = ScanReport(path=path, file_size=path.stat().st_size)
            scans.append(report)
            schemas: dict[int, Schema] = {}
            handles: dict[int, int] = {}
            base = done
            for record in scan_mcap(path, report, lambda pos: progress.update(base + pos)):
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel) and record.id not in handles:
                    if writer is None:
                        writer = BagWriter(out, custom_data={'repaired_from': str(bag.resolve())})
                        writer.open()
                    topic = _topic_from(record, schemas.get(record.schema_id))
                    known = [i for i, t in enumerate(writer.topics) if t.name == topic.name]
                    handles[record.id] = known[0] if known else writer.add_topic(topic)
                elif isinstance(record, Message):
                    if record.channel_id not in handles:
                        continue
                    assert writer is not None
                    writer.write(handles[record.channel_id], record.log_time, record.data, record.publish_time)
            if report.profile and report.profile != 'ros2':
                raise RepairError(f'{path} has MCAP profile {report.profile!r}, not ros2')
            done += report.file_size
            progress.update(done)
        if writer is None:
            reasons = '; '.join(s.stop_reason for s in scans)
            raise RepairError(f'nothing recoverable in {bag}: no complete chunk with a channel ({reasons})')
        writer.custom_data = {**_recorded_custom_data(scans), **writer.custom_data}
        return RepairResult(writer.close(), scans)
    except OSError as err:
        if writer is not None and writer.is_open:
            writer.abort()
        raise RepairError(f'{err.filename or bag}: {err.strerror}') from None
    except BaseException:
        if writer is not None and writer.is_open:
            writer.abort()
        raise


def build_parser() -> argparse.ArgumentParser:
    """Command-line interface of bag_repair."""
    parser = argparse.ArgumentParser(
        prog='bag_repair',
        description='Rebuild an interrupted rosbag2/MCAP bag (index, summary, metadata.yaml) into a new folder, '
        'reading every complete chunk and stopping at the first truncated or corrupt record. '
        'The original bag is not modified.',
    )
    parser.add_argument('bag', type=Path, help='bag folder (or a single .mcap file) to repair')
    parser.add_argument('-o', '--out', type=Path, help='folder of the repaired bag (default: <bag>_repaired)')
    parser.add_argument('--json', type=Path, help='also write the result as JSON to this file')
    parser.add_argument('-q', '--quiet', action='store_true', help='no progress lines')
    return parser


def _main(argv: Optional[Sequence[str]]) -> int:
    """Parse arguments, repair, print the one-line result."""
    args = build_parser().parse_args(argv)
    result = repair_bag(args.bag, args.out, quiet=args.quiet)
    print(result.line())
    if args.json:
        doc: dict[str, Any] = {
            'path': str(result.summary.path),
            'counts': result.summary.counts,
            'scans': [
                {'file': str(s.path), 'stop_reason': s.stop_reason, 'complete': s.complete,
                 'bytes_lost': s.bytes_lost, 'chunks': s.chunks}
                for s in result.scans
            ],
        }
        args.json.write_text(json.dumps(doc, indent=2) + '\n', encoding='utf-8')
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``bag_repair``."""
    return run_cli('bag_repair', _main, argv)


if __name__ == '__main__':
    raise SystemExit(main())
