# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``bag_repair``: rebuild a bag whose recorder died (no MCAP summary or footer, no metadata.yaml).

The MCAP files of the bag are scanned record by record (scan.py). Schemas, channels and
messages are taken from every complete, CRC-valid chunk; after a truncated or corrupt record
the scan resynchronises at the next plausible record, so every intact chunk is recovered,
and each skipped byte range is reported with the number of messages it held (or unknown).
What was read is written to a NEW bag folder (default ``<bag>_repaired``) with a fresh MCAP
index and metadata.yaml; the original files are only read, never modified. Output locations
are checked before any work (outputs.py); a repair that fails removes what it wrote.
"""

from __future__ import annotations

import argparse
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Optional, Sequence, Union

import yaml
from mcap.records import Channel, Message, Schema
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import TypesysError

from .bag_format import BagSummary, BagWriter, TopicSpec, qos_from_yaml
from .datafile import describe_os_error
from .errors import BagWriteError, RepairError, run_cli
from .outputs import check_output_file, check_output_folder, source_folders
from .progress import Progress
from .scan import Loss, ScanReport, scan_mcap, summary_definitions

__all__ = [
    'Loss',
    'RepairResult',
    'ScanReport',
    'default_output',
    'main',
    'mcap_files',
    'repair_bag',
    'scan_mcap',
]


def mcap_files(bag: Path) -> list[Path]:
    """List the MCAP files of a bag folder (or the file itself), in recording order."""
    if bag.is_file():
        return [bag]
    if not bag.is_dir():
        raise RepairError(f'{bag} does not exist')
    files = sorted(bag.glob('*.mcap'), key=lambda p: (len(p.name), p.name))
    if not files:
        raise RepairError(f'{bag} holds no .mcap file, so it is not an MCAP bag')
    return files


def default_output(bag: Path) -> Path:
    """``<bag>_repaired`` beside the bag folder (for a lone .mcap file: beside it, by its stem)."""
    if bag.is_file() and source_folders([bag]):
        bag = bag.parent
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
        definition = schema.data.decode('utf-8')
    except UnicodeDecodeError:
        raise RepairError(
            f'channel {channel.topic}: the text of its schema {schema.name!r} is not UTF-8 '
            '(damaged); cannot rebuild it'
        ) from None
    try:
        qos = qos_from_yaml(channel.metadata.get('offered_qos_profiles', ''))
    except (yaml.YAMLError, KeyError, TypeError, ValueError, BagWriteError):
        qos = ()
    return TopicSpec(
        name=channel.topic,
        msgtype=schema.name,
        definition=definition,
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

    @property
    def bytes_lost(self) -> int:
        """Bytes skipped in every file."""
        return sum(s.bytes_lost for s in self.scans)

    @property
    def messages_lost(self) -> Optional[int]:
        """Messages known lost in every file; None when some loss is uncounted."""
        counts = [s.messages_lost for s in self.scans]
        return None if any(n is None for n in counts) else sum(n or 0 for n in counts)

    def line(self) -> str:
        """One-line human summary.

        What was written, why each scan stopped, and exactly what was lost.
        """
        how = '; '.join(f'{s.path.name}: {s.stop_reason}' for s in self.scans)
        lost = self.messages_lost
        details = [f'{s.path.name} {loss.text()}' for s in self.scans for loss in s.losses]
        details += [
            f'{s.path.name}: {s.without_channel} messages of intact chunks '
            'whose channel was defined in a lost part'
            for s in self.scans
            if s.without_channel
        ]
        counted = sum(s.messages_lost_counted for s in self.scans)
        if lost is not None:
            amount = str(lost)
        else:
            amount = f'at least {counted}' if counted else 'an unknown number of'
        return (
            f'repaired {self.summary.line()}; {how}; {self.bytes_lost} bytes not recoverable, '
            f'{amount} messages lost' + (f' ({"; ".join(details)})' if details else '')
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON form: the repaired bag, its counts, per file the scan and every skipped range."""
        lost = self.messages_lost
        return {
            'path': str(self.summary.path),
            'counts': self.summary.counts,
            'bytes_lost': self.bytes_lost,
            'messages_lost': 'unknown' if lost is None else lost,
            'messages_lost_counted': sum(s.messages_lost_counted for s in self.scans),
            'scans': [s.as_dict() for s in self.scans],
        }


class _RepairedBag:
    """The new bag folder, created at the first channel registered; one writer topic per name."""

    def __init__(self, out: Path, bag: Path) -> None:
        """Write to ``out`` (not created yet) what is readable of ``bag``."""
        self.out = out
        self.bag = bag
        self.writer: Optional[BagWriter] = None

    def handle(self, channel: Channel, schema: Optional[Schema]) -> int:
        """Writer handle of the channel's topic (bag opened, topic added when first met)."""
        if self.writer is None:
            self.writer = BagWriter(
                self.out, custom_data={'repaired_from': str(self.bag.resolve())}
            )
            self.writer.open()
        topic = _topic_from(channel, schema)
        known = [i for i, t in enumerate(self.writer.topics) if t.name == topic.name]
        return known[0] if known else self.writer.add_topic(topic)


def _repair_file(
    path: Path, report: ScanReport, repaired: _RepairedBag, on_progress: Callable[[int], None]
) -> None:
    """Copy what the scan of one MCAP file reads into the repaired bag (``report``: the rest)."""
    # The summary's definitions (closed files only) stand in for those lost with a damaged chunk.
    spare_schemas, spare_channels = summary_definitions(path)
    schemas: dict[int, Schema] = {}
    handles: dict[int, int] = {}

    def register(channel: Channel) -> None:
        schema = schemas.get(channel.schema_id) or spare_schemas.get(channel.schema_id)
        handles[channel.id] = repaired.handle(channel, schema)

    for record in scan_mcap(path, report, on_progress):
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel) and record.id not in handles:
            register(record)
        elif isinstance(record, Message):
            if record.channel_id not in handles and record.channel_id in spare_channels:
                register(spare_channels[record.channel_id])
            if record.channel_id not in handles:
                report.without_channel += 1
                continue
            assert repaired.writer is not None
            repaired.writer.write(
                handles[record.channel_id],
                record.log_time,
                record.data,
                record.publish_time,
            )
    # rosbag2 writes the channel of a topic that never had a message only in the summary: keep
    # it, as ``ros2 bag info`` shows it (0 messages).
    for channel_id, channel in spare_channels.items():
        if channel_id not in handles and channel.schema_id in spare_schemas:
            register(channel)
    if report.profile and report.profile != 'ros2':
        raise RepairError(f'{path} has MCAP profile {report.profile!r}, not ros2')


def _nothing_recoverable(bag: Path, scans: Sequence[ScanReport]) -> RepairError:
    """Build the error of a repair that found no complete chunk with a channel (and why)."""
    reasons = '; '.join(s.stop_reason for s in scans)
    orphans = sum(s.without_channel for s in scans)
    if orphans:
        reasons += (
            f'; {orphans} messages of intact chunks whose channel was defined in a lost part'
        )
    return RepairError(
        f'nothing recoverable in {bag}: no complete chunk with a channel ({reasons})'
    )


def repair_bag(
    bag: Union[str, os.PathLike], out: Union[str, os.PathLike, None] = None, *, quiet: bool = False
) -> RepairResult:
    """Scan the bag's MCAP files and write what is readable to the new bag folder ``out``."""
    bag = Path(bag)
    files = mcap_files(bag)
    out = Path(out) if out is not None else default_output(bag)
    check_output_folder('output', out, [bag])
    if out.exists():
        full = out.is_dir() and any(out.iterdir())
        raise RepairError(
            f'{out} exists already{" and is not empty" if full else ""}, not overwriting'
        )
    total = sum(p.stat().st_size for p in files)
    progress = Progress(f'bag_repair {bag.name}', total, unit='bytes', enabled=not quiet)
    repaired = _RepairedBag(out, bag)
    scans: list[ScanReport] = []
    done = 0
    try:
        for path in files:
            report = ScanReport(path=path, file_size=path.stat().st_size)
            scans.append(report)
            base = done
            _repair_file(path, report, repaired, lambda pos: progress.update(base + pos))
            done += report.file_size
            progress.update(done)
        writer = repaired.writer
        if writer is None:
            raise _nothing_recoverable(bag, scans)
        writer.custom_data = {**_recorded_custom_data(scans), **writer.custom_data}
        return RepairResult(writer.close(), scans)
    except OSError as err:
        if repaired.writer is not None:
            repaired.writer.discard()
        raise RepairError(f'{err.filename or bag}: {describe_os_error(err)}') from None
    except BaseException as err:
        if repaired.writer is not None:
            repaired.writer.discard()
        if isinstance(err, BagWriteError) and not isinstance(err, RepairError):
            raise RepairError(f'{err}; nothing was left in {out}') from None
        raise


def build_parser() -> argparse.ArgumentParser:
    """Command-line interface of bag_repair."""
    parser = argparse.ArgumentParser(
        prog='bag_repair',
        description='Rebuild an interrupted rosbag2/MCAP bag (index, summary, metadata.yaml) '
        'into a new folder, reading every complete chunk; after a truncated or corrupt record '
        'it resynchronises at the next intact one and reports every skipped byte range. '
        'The original bag is not modified; the output must be a new folder outside it.',
    )
    parser.add_argument('bag', type=Path, help='bag folder (or a single .mcap file) to repair')
    parser.add_argument(
        '-o', '--out', type=Path, help='folder of the repaired bag (default: <bag>_repaired)'
    )
    parser.add_argument('--json', type=Path, help='also write the result as JSON to this file')
    parser.add_argument('-q', '--quiet', action='store_true', help='no progress lines')
    return parser


def _main(argv: Optional[Sequence[str]]) -> int:
    """Parse arguments, repair, print the one-line result."""
    args = build_parser().parse_args(argv)
    if args.json:
        out = args.out if args.out is not None else default_output(args.bag)
        check_output_file('--json', args.json, [args.bag], created=[out])
    result = repair_bag(args.bag, args.out, quiet=args.quiet)
    print(result.line())
    if args.json:
        try:
            args.json.write_text(json.dumps(result.as_dict(), indent=2) + '\n', encoding='utf-8')
        except OSError as err:
            raise RepairError(
                f'cannot write {args.json}: {describe_os_error(err)} '
                f'(the repaired bag {result.summary.path} is complete)'
            ) from None
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``bag_repair``."""
    return run_cli('bag_repair', _main, argv)


if __name__ == '__main__':
    raise SystemExit(main())
