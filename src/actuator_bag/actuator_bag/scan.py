# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Record-by-record scan of one MCAP file that survives damage and says exactly what it skipped.

The scan reads the data section in file order. A record that is truncated, has an unknown
opcode, does not decode to exactly its length, or is a chunk that fails to decompress or its
CRC, is damage: the scan resynchronises at the next plausible record (a known opcode whose
length fits the file and whose fields decode to exactly that length; for a chunk, also a
CRC that validates) and goes on, so every intact chunk after the damage is read. Each skipped
byte range is a Loss with its reason and, when the damaged chunk's extent is intact and its
message index records follow it intact, the number of messages it held (else unknown).
"""

from __future__ import annotations

import mmap
import re
import struct
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import Any, Callable, Iterator, Optional, Union

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Metadata,
    Schema,
)
from mcap.stream_reader import CRCValidationError, breakup_chunk

from .errors import RepairError

MCAP_MAGIC = b'\x89MCAP0\r\n'
_RECORD_HEADER = struct.Struct('<BQ')
_HEAD = _RECORD_HEADER.size
#: Largest uncompressed chunk accepted (a damaged size field must not make the scan allocate
#: more) [bytes].
MAX_CHUNK_BYTES = 1 << 30
_COMPRESSIONS = ('', 'zstd', 'lz4')
_KNOWN = frozenset(int(o) for o in Opcode)
#: Opcodes a resynchronisation may land on (records a data section of this project's bags holds).
_RESYNC = re.compile(
    b'['
    + re.escape(
        bytes(
            sorted(
                {
                    Opcode.CHUNK,
                    Opcode.MESSAGE_INDEX,
                    Opcode.SCHEMA,
                    Opcode.CHANNEL,
                    Opcode.METADATA,
                    Opcode.DATA_END,
                    Opcode.FOOTER,
                }
            )
        )
    )
    + b']'
)
_DECODERS: dict[int, Callable[[ReadDataStream, int], Any]] = {
    Opcode.HEADER: lambda s, n: Header.read(s),
    Opcode.SCHEMA: lambda s, n: Schema.read(s),
    Opcode.CHANNEL: lambda s, n: Channel.read(s),
    Opcode.MESSAGE: Message.read,
    Opcode.CHUNK: lambda s, n: Chunk.read(s),
    Opcode.MESSAGE_INDEX: lambda s, n: MessageIndex.read(s),
    Opcode.METADATA: lambda s, n: Metadata.read(s),
    Opcode.DATA_END: lambda s, n: DataEnd.read(s),
    Opcode.FOOTER: lambda s, n: Footer.read(s),
}
_DECODE_ERRORS = (
    McapError,
    CRCValidationError,
    ValueError,
    struct.error,
    UnicodeDecodeError,
    OverflowError,
)

Record = Union[Schema, Channel, Message, Metadata]


@dataclass
class Loss:
    """One skipped byte range [start, end) of a file, why, and how many messages it held.

    ``messages`` None: unknown.
    """

    start: int
    end: int
    reason: str
    messages: Optional[int] = None

    @property
    def size(self) -> int:
        """Bytes skipped."""
        return self.end - self.start

    def text(self) -> str:
        """``bytes A-B (N bytes, M messages): reason``."""
        count = 'unknown number of' if self.messages is None else str(self.messages)
        return (
            f'bytes {self.start}-{self.end} ({self.size} bytes, {count} messages): {self.reason}'
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON form; messages is 'unknown' when the damaged records do not say."""
        return {
            'start': self.start,
            'end': self.end,
            'bytes': self.size,
            'reason': self.reason,
            'messages': 'unknown' if self.messages is None else self.messages,
        }


@dataclass
class ScanReport:
    """Outcome of scanning one MCAP file.

    Where and why it stopped, what it found, what it skipped.
    """

    path: Path
    file_size: int
    bytes_read: int = 0
    complete: bool = False
    stop_reason: str = ''
    chunks: int = 0
    messages: int = 0
    profile: str = ''
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    losses: list[Loss] = field(default_factory=list)
    #: Messages of intact chunks left out because their channel was defined in a damaged part.
    without_channel: int = 0

    @property
    def bytes_lost(self) -> int:
        """Bytes skipped as damaged or truncated (not recoverable)."""
        return sum(loss.size for loss in self.losses)

    @property
    def messages_lost(self) -> Optional[int]:
        """Messages known lost (damaged chunks plus messages without channel).

        None when a loss is uncounted.
        """
        if any(loss.messages is None for loss in self.losses):
            return None
        return self.messages_lost_counted

    @property
    def messages_lost_counted(self) -> int:
        """Messages lost in the ranges whose count is known, plus messages without channel.

        A lower bound.
        """
        return sum(loss.messages or 0 for loss in self.losses) + self.without_channel

    def as_dict(self) -> dict[str, Any]:
        """JSON form of the report."""
        lost = self.messages_lost
        return {
            'file': str(self.path),
            'stop_reason': self.stop_reason,
            'complete': self.complete,
            'bytes_lost': self.bytes_lost,
            'chunks': self.chunks,
            'messages': self.messages,
            'messages_lost': 'unknown' if lost is None else lost,
            'messages_lost_counted': self.messages_lost_counted,
            'messages_without_channel': self.without_channel,
            'losses': [loss.as_dict() for loss in self.losses],
        }


class _Damage(Exception):
    """The bytes at a position are not a valid record.

    ``length`` is set when its framing is trusted.
    """

    # The framing is trusted for a chunk whose fields decode to exactly its length but whose data
    # fails to decompress or its CRC: its extent can then be skipped exactly.

    def __init__(self, reason: str, length: Optional[int] = None) -> None:
        """Keep a reason, and the record length when the framing is trusted."""
        super().__init__(reason)
        self.length = length


def _decode(buf: Any, pos: int, size: int) -> tuple[int, int, Any]:
    """Decode the record at ``pos`` into (opcode, length, record).

    _Damage unless it decodes to exactly its length.
    """
    if size - pos < _HEAD:
        raise _Damage(f'truncated record header at byte {pos}')
    opcode, length = _RECORD_HEADER.unpack_from(buf, pos)
    if opcode not in _KNOWN:
        raise _Damage(f'unknown opcode 0x{opcode:02x} at byte {pos}')
    name = Opcode(opcode).name
    if length > size - pos - _HEAD:
        raise _Damage(f'truncated {name} record at byte {pos}')
    stream = ReadDataStream(BytesIO(buf[pos + _HEAD : pos + _HEAD + length]))
    try:
        record = _DECODERS[opcode](stream, length) if opcode in _DECODERS else None
        if record is not None and stream.count != length:
            raise ValueError(f'fields take {stream.count} of its {length} bytes')
    except _DECODE_ERRORS as err:
        raise _Damage(f'corrupt {name} record at byte {pos} ({err})') from None
    if isinstance(record, Chunk):
        try:
            record = _chunk_records(record)
        except _DECODE_ERRORS as err:
            raise _Damage(f'corrupt {name} record at byte {pos} ({err})', length) from None
    return opcode, length, record


def _chunk_records(chunk: Chunk) -> list:
    """Return the records of a chunk, its CRC validated.

    ValueError when it is implausible or damaged.
    """
    if chunk.compression not in _COMPRESSIONS:
        raise ValueError(f'unknown compression {chunk.compression!r}')
    if chunk.uncompressed_size > MAX_CHUNK_BYTES:
        raise ValueError(f'uncompressed size {chunk.uncompressed_size} is implausible')
    try:
        return breakup_chunk(chunk, validate_crc=True)
    except (CRCValidationError, McapError, struct.error):
        raise
    except Exception as err:  # noqa: BLE001 - zstd/lz4 raise their own error classes on damaged data
        raise ValueError(f'does not decompress: {err}') from None


def _resync(buf: Any, start: int, size: int) -> Optional[int]:
    """Position of the next plausible record at or after ``start`` (None: none before the end)."""
    for match in _RESYNC.finditer(buf, start):
        pos = match.start()
        if size - pos < _HEAD or _RECORD_HEADER.unpack_from(buf, pos)[1] > size - pos - _HEAD:
            continue
        try:
            opcode, length, _ = _decode(buf, pos, size)
        except _Damage:
            continue
        if opcode == Opcode.FOOTER and pos + _HEAD + length + len(MCAP_MAGIC) != size:
            continue
        return pos
    return None


def _indexed_messages(buf: Any, pos: int, size: int) -> Optional[int]:
    """Count the messages listed by the message index records starting at ``pos`` (a chunk's).

    None unless intact.
    """
    total, found = 0, False
    while pos < size:
        if size - pos < _HEAD:
            return None
        opcode, length = _RECORD_HEADER.unpack_from(buf, pos)
        if opcode != Opcode.MESSAGE_INDEX:
            # The group ends at the next record; its header must look sound, else the group may be
            # cut short.
            sound = opcode in _KNOWN and length <= size - pos - _HEAD
            return total if found and sound else None
        try:
            _, _, record = _decode(buf, pos, size)
        except _Damage:
            return None
        total += len(record.records)
        found = True
        pos += _HEAD + length
    return total if found else None


def summary_definitions(path: Path) -> tuple[dict[int, Schema], dict[int, Channel]]:
    """Schemas and channels of the file's summary section when its footer is intact, else none.

    The footer is intact in a closed file.
    """
    # They stand in for definitions lost with a damaged chunk: a writer puts each schema and
    # channel only in the chunk where it is first used, and repeats them all in the summary at
    # close.
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    if path.stat().st_size < 2 * len(MCAP_MAGIC) + _HEAD + 20:
        return schemas, channels
    with open(path, 'rb') as bio, mmap.mmap(bio.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        size = len(buf)
        foot = size - len(MCAP_MAGIC) - _HEAD - 20
        if foot < len(MCAP_MAGIC) or buf[size - len(MCAP_MAGIC) :] != MCAP_MAGIC:
            return schemas, channels
        try:
            opcode, _, footer = _decode(buf, foot, size - len(MCAP_MAGIC))
        except _Damage:
            return schemas, channels
        if opcode != Opcode.FOOTER:
            return schemas, channels
        pos, end = footer.summary_start, footer.summary_offset_start or foot
        if not len(MCAP_MAGIC) <= pos <= end <= foot:
            return schemas, channels
        while pos < end:
            try:
                opcode, length, record = _decode(buf, pos, end)
            except _Damage:
                break
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            pos += _HEAD + length
    return schemas, channels


def scan_mcap(
    path: Path, report: ScanReport, on_progress: Optional[Callable[[int], None]] = None
) -> Iterator[Record]:
    """Yield an MCAP file's schemas, channels, messages, metadata in file order, skipping damage.

    ``report`` says what was skipped.
    """
    with open(path, 'rb') as bio:
        if bio.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise RepairError(f'{path} is not an MCAP file (bad magic)')
        size = report.file_size
        with mmap.mmap(bio.fileno(), 0, access=mmap.ACCESS_READ) as buf:
            yield from _scan(buf, size, report, on_progress)


def _skip_damage(
    buf: Any, pos: int, size: int, report: ScanReport, damage: _Damage
) -> Optional[int]:
    """Report the damage at ``pos`` as a Loss; return where the scan goes on (None: it stops)."""
    reason = str(damage)
    messages = None
    if damage.length is not None:
        # The chunk's framing is intact: skip exactly it and count its messages from its index.
        chunk_end = pos + _HEAD + damage.length
        end: Optional[int] = chunk_end
        messages = _indexed_messages(buf, chunk_end, size)
    else:
        end = _resync(buf, pos + 1, size)
    if end is None:
        report.losses.append(Loss(pos, size, reason))
        report.stop_reason = reason
        report.bytes_read = size
        return None
    report.losses.append(Loss(pos, end, reason, messages))
    return end


def _records(opcode: int, record: Any, report: ScanReport) -> Iterator[Record]:
    """Yield what a decoded record holds for the caller (a chunk: its records), counting it."""
    if opcode == Opcode.HEADER:
        report.profile = record.profile
    elif opcode == Opcode.METADATA:
        report.metadata[record.name] = dict(record.metadata)
        yield record
    elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
        yield record
    elif opcode == Opcode.MESSAGE:
        report.messages += 1
        yield record
    elif opcode == Opcode.CHUNK:
        report.chunks += 1
        for inner in record:
            if isinstance(inner, Message):
                report.messages += 1
            if isinstance(inner, (Schema, Channel, Message)):
                yield inner


def _scan(
    buf: Any, size: int, report: ScanReport, on_progress: Optional[Callable[[int], None]]
) -> Iterator[Record]:
    """Run the scan of scan_mcap over the mapped file."""
    pos = len(MCAP_MAGIC)
    report.bytes_read = pos
    while True:
        if pos >= size:
            report.stop_reason = f'file ends at byte {pos} without MCAP footer'
            return
        try:
            opcode, length, record = _decode(buf, pos, size)
        except _Damage as damage:
            end = _skip_damage(buf, pos, size, report, damage)
            if end is None:
                return
            pos = report.bytes_read = end
            continue
        yield from _records(opcode, record, report)
        if opcode in (Opcode.DATA_END, Opcode.FOOTER):
            report.complete = True
            report.stop_reason = 'end of data section'
            report.bytes_read = pos + _HEAD + length
            return
        pos += _HEAD + length
        report.bytes_read = pos
        if on_progress is not None:
            on_progress(pos)
