# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Writing rosbag2 bags as ROS 2 Jazzy does.

A bag is a folder with metadata.yaml (version 9) and one MCAP file. The MCAP file has profile
``ros2``, one ``ros2msg`` schema per type holding the full definition text, ``cdr`` channels
whose metadata carry ``offered_qos_profiles`` (a YAML string) and ``topic_type_hash``
(RIHS01), zstd-compressed chunks with CRCs, and a Metadata record ``rosbag2`` whose
``serialized_metadata`` is the YAML of the bag metadata.

The ``mcap`` library's Writer is used rather than rosbags' Writer because only it lets the
channel metadata carry ``topic_type_hash``, names the file ``<name>_0.mcap`` as rosbag2
does, marks ``ros_distro: jazzy`` and can flush a finished chunk to disk on demand
(rosbags keeps up to 1 MiB in memory until close). That flush is what makes a
recording survive a SIGKILL: see repair.py.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, Iterable, Mapping, Optional, Sequence

import yaml
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from .bag_qos import DURATION_INFINITE, QosProfile, qos_from_yaml, qos_to_yaml
from .datafile import DataFile, describe_os_error, open_data_file
from .errors import BagIOError, BagWriteError
from .msgdefs import DefinitionSource, normalize_msgtype

__all__ = [
    'DEFAULT_CHUNK_SIZE',
    'DEFAULT_FLUSH_INTERVAL_S',
    'DURATION_INFINITE',
    'METADATA_VERSION',
    'ROS_DISTRO',
    'BagSummary',
    'BagWriter',
    'QosProfile',
    'TopicSpec',
    'bag_metadata',
    'dump_yaml',
    'mcap_name',
    'qos_from_yaml',
    'qos_to_yaml',
    'topic_spec',
    'write_metadata_file',
]

#: rosbag2 metadata format version written (Jazzy).
METADATA_VERSION = 9
#: ROS distribution recorded in the metadata.
ROS_DISTRO = 'jazzy'
#: Default size of an MCAP chunk before compression [bytes].
DEFAULT_CHUNK_SIZE = 1 << 20
#: Default longest time data may stay in memory before it is written to the file [s].
DEFAULT_FLUSH_INTERVAL_S = 1.0


def _library_id() -> str:
    """Writer identification for the MCAP header."""
    try:
        own = version('actuator_bag')
    except PackageNotFoundError:
        own = 'dev'
    try:
        lib = version('mcap')
    except PackageNotFoundError:
        lib = 'unknown'
    return f'actuator_bag-{own}; mcap-python-{lib}'


@dataclass(frozen=True)
class TopicSpec:
    """Everything recorded about one topic: name, type, full definition, type hash, offered QoS."""

    name: str
    msgtype: str
    definition: str
    type_hash: str
    qos: tuple[QosProfile, ...] = ()
    serialization_format: str = 'cdr'
    definition_encoding: str = 'ros2msg'

    def __post_init__(self) -> None:
        """Validate names and encodings."""
        if not self.name.startswith('/') or self.name.endswith('/') or '//' in self.name:
            raise BagWriteError(
                f'topic name must be fully qualified like /ns/topic, not {self.name!r}'
            )
        object.__setattr__(self, 'msgtype', normalize_msgtype(self.msgtype))
        if self.serialization_format != 'cdr':
            raise BagWriteError(
                f'only cdr serialization is supported, not {self.serialization_format!r}'
            )
        if self.definition_encoding not in ('ros2msg', 'ros2idl'):
            raise BagWriteError(f'unknown definition encoding {self.definition_encoding!r}')


def topic_spec(
    name: str,
    msgtype: str,
    source: DefinitionSource,
    qos: Iterable[QosProfile] = (),
    type_hash: Optional[str] = None,
) -> TopicSpec:
    """Make a TopicSpec with the definition taken from a DefinitionSource.

    The hash too is taken from it, unless given.
    """
    return TopicSpec(
        name=name,
        msgtype=msgtype,
        definition=source.full_text(msgtype),
        type_hash=type_hash or source.type_hash(msgtype),
        qos=tuple(qos),
    )


@dataclass
class BagSummary:
    """What a closed bag holds: path, messages per topic, first and last log time [ns]."""

    path: Path
    counts: dict[str, int] = field(default_factory=dict)
    start_ns: int = 0
    end_ns: int = 0

    @property
    def message_count(self) -> int:
        """Total number of messages."""
        return sum(self.counts.values())

    @property
    def duration_s(self) -> float:
        """Span of the log times [s]."""
        return (self.end_ns - self.start_ns) * 1e-9

    def line(self) -> str:
        """One-line human summary."""
        per_topic = ', '.join(f'{k}={v}' for k, v in self.counts.items()) or 'no topics'
        return (
            f'{self.path}: {self.message_count} messages in {self.duration_s:.3f} s ({per_topic})'
        )


def mcap_name(bag_dir: os.PathLike | str) -> str:
    """Name the (only) MCAP file of a bag folder as rosbag2 does: ``<name>_0.mcap``."""
    return f'{Path(bag_dir).name}_0.mcap'


def bag_metadata(
    files: Sequence[str],
    topics: Sequence[TopicSpec],
    counts: Sequence[int],
    start_ns: int,
    end_ns: int,
    custom_data: Optional[Mapping[str, str]] = None,
) -> dict[str, Any]:
    """Build the ``rosbag2_bagfile_information`` map for one file.

    Version 9, with every version-gated key present.
    """
    if len(topics) != len(counts):
        raise BagWriteError('one message count per topic is needed')
    total = int(sum(counts))
    start = int(start_ns) if total else 0
    duration = max(0, int(end_ns) - int(start_ns)) if total else 0
    return {
        'version': METADATA_VERSION,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': total,
        'topics_with_message_count': [
            {
                'topic_metadata': {
                    'name': t.name,
                    'type': t.msgtype,
                    'serialization_format': t.serialization_format,
                    'offered_qos_profiles': [q.as_dict() for q in t.qos],
                    'type_description_hash': t.type_hash,
                },
                'message_count': int(n),
            }
            for t, n in zip(topics, counts)
        ],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': list(files),
        'files': [
            {
                'path': name,
                'starting_time': {'nanoseconds_since_epoch': start},
                'duration': {'nanoseconds': duration},
                'message_count': total,
            }
            for name in files
        ],
        'custom_data': dict(custom_data) if custom_data else {},
        'ros_distro': ROS_DISTRO,
    }


def dump_yaml(data: Any) -> str:
    """Block-style YAML text keeping key order."""
    return yaml.safe_dump(data, default_flow_style=False, sort_keys=False, allow_unicode=True)


def write_metadata_file(bag_dir: os.PathLike | str, info: Mapping[str, Any]) -> Path:
    """Write ``metadata.yaml`` atomically (temporary file, then rename); return its path."""
    path = Path(bag_dir) / 'metadata.yaml'
    tmp = path.with_name('.metadata.yaml.tmp')
    try:
        tmp.write_text(dump_yaml({'rosbag2_bagfile_information': dict(info)}), encoding='utf-8')
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
        raise
    return path


class BagWriter:
    """Writes one rosbag2 bag folder; never overwrites; flushes chunks to disk regularly.

    Use as a context manager, or call open(), add_topic(), write() and close().
    Not thread-safe: call it from one thread (the recorder uses a writer thread).
    A failed write (disk full, I/O error) raises BagIOError once: the file is cut back to its
    last complete chunk and closed, the writer is closed, ``durable`` says how many messages
    reached the file, and discard() removes what open() created.
    """

    def __init__(
        self,
        path: os.PathLike | str,
        *,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S,
        compression: str = 'zstd',
        custom_data: Optional[Mapping[str, str]] = None,
    ) -> None:
        """Prepare writing the bag folder ``path`` (which must not exist yet)."""
        self.path = Path(path)
        if chunk_size < 1024:
            raise BagWriteError(f'chunk_size must be at least 1024 bytes, not {chunk_size}')
        if not flush_interval_s > 0:
            raise BagWriteError(f'flush_interval_s must be > 0, not {flush_interval_s}')
        if compression not in ('zstd', 'none'):
            raise BagWriteError(f'compression must be zstd or none, not {compression!r}')
        if custom_data and not all(isinstance(v, str) for v in custom_data.values()):
            raise BagWriteError('custom_data values must be strings')
        if self.path.exists():
            raise BagWriteError(f'{self.path} exists already, not overwriting')
        self.chunk_size = int(chunk_size)
        self.flush_interval_s = float(flush_interval_s)
        self.compression = compression
        self.custom_data = dict(custom_data or {})
        self.mcap_path = self.path / mcap_name(self.path)
        self.topics: list[TopicSpec] = []
        self.counts: list[int] = []
        self.start_ns = 0
        self.end_ns = 0
        self._file: Optional[DataFile] = None
        self._created: list[Path] = []
        #: Messages known to be in the file (complete chunks written), as opposed to ``counts``
        #: (accepted).
        self.durable = 0
        self._mcap: Optional[McapWriter] = None
        self._schemas: dict[tuple[str, str], int] = {}
        self._channels: list[int] = []
        self._last_flush = time.monotonic()
        self._unflushed = 0

    @property
    def is_open(self) -> bool:
        """True between open() and close()/abort()."""
        return self._mcap is not None

    def open(self) -> None:
        """Create the folder and the MCAP file and write the MCAP header."""
        if self._mcap is not None:
            raise BagWriteError(f'{self.path} is already open')
        missing = [p for p in (self.path, *self.path.parents) if not p.exists()]
        try:
            self.path.mkdir(parents=True, exist_ok=False)
        except FileExistsError:
            raise BagWriteError(f'{self.path} exists already, not overwriting') from None
        except OSError as err:
            raise BagWriteError(f'cannot create {self.path}: {err.strerror}') from None
        self._created = list(missing)
        try:
            self._file = open_data_file(self.mcap_path)
            self._created.insert(0, self.mcap_path)
            self._mcap = McapWriter(
                # mcap types its output as a file object; it calls only write() and tell()
                self._file,  # type: ignore[arg-type]
                chunk_size=self.chunk_size,
                compression=CompressionType.ZSTD
                if self.compression == 'zstd'
                else CompressionType.NONE,
                enable_crcs=True,
            )
            self._mcap.start(profile='ros2', library=_library_id())
        except OSError as err:
            self._mcap = None
            self.discard()
            raise BagIOError(
                f'cannot create {self.mcap_path}: {describe_os_error(err)}', err.errno
            ) from None
        self._last_flush = time.monotonic()

    def _failed(self, err: OSError, doing: str, good_before: int) -> BagIOError:
        """Cut the file back to its last complete write, close it; the BagIOError to raise."""
        if self._file is not None:
            # Grown since good_before: the chunk went out and its index write failed, so its
            # messages are in.
            if self._file.good != good_before:
                self.durable = sum(self.counts)
            self._file.cut_back()
        self.abort()
        return BagIOError(f'{doing} {self.mcap_path} failed: {describe_os_error(err)}', err.errno)

    def _writer(self) -> McapWriter:
        """Return the open MCAP writer, or raise BagWriteError."""
        if self._mcap is None:
            raise BagWriteError(f'{self.path} is not open')
        return self._mcap

    def add_topic(self, topic: TopicSpec) -> int:
        """Register a topic; return the handle to pass to write()."""
        writer = self._writer()
        if any(t.name == topic.name for t in self.topics):
            raise BagWriteError(f'topic {topic.name} is already in {self.path}')
        key = (topic.msgtype, topic.definition)
        if key not in self._schemas:
            self._schemas[key] = writer.register_schema(
                name=topic.msgtype,
                encoding=topic.definition_encoding,
                data=topic.definition.encode('utf-8'),
            )
        channel = writer.register_channel(
            topic=topic.name,
            message_encoding=topic.serialization_format,
            schema_id=self._schemas[key],
            metadata={
                'offered_qos_profiles': qos_to_yaml(topic.qos),
                'topic_type_hash': topic.type_hash,
            },
        )
        self.topics.append(topic)
        self.counts.append(0)
        self._channels.append(channel)
        return len(self.topics) - 1

    def write(
        self, handle: int, log_time_ns: int, data: bytes, publish_time_ns: Optional[int] = None
    ) -> None:
        """Append one serialized (CDR) message of topic ``handle`` received at ``log_time_ns``."""
        writer = self._writer()
        if not 0 <= handle < len(self._channels):
            raise BagWriteError(f'unknown topic handle {handle}')
        if log_time_ns < 0:
            raise BagWriteError(f'log time must be >= 0 ns, not {log_time_ns}')
        if not any(self.counts):
            self.start_ns = self.end_ns = int(log_time_ns)
        else:
            self.start_ns = min(self.start_ns, int(log_time_ns))
            self.end_ns = max(self.end_ns, int(log_time_ns))
        self.counts[handle] += 1
        written = self._file.good if self._file is not None else 0
        try:
            writer.add_message(
                channel_id=self._channels[handle],
                log_time=int(log_time_ns),
                data=data,
                publish_time=int(log_time_ns if publish_time_ns is None else publish_time_ns),
            )
        except OSError as err:
            raise self._failed(err, 'writing', written) from None
        if self._file is not None and self._file.good != written:
            self.durable = sum(self.counts)  # a chunk (holding this message) went to the file
        self._unflushed += len(data) + 31
        if self._unflushed >= self.chunk_size:
            self.flush()
        else:
            self.flush_if_due()

    def flush_if_due(self) -> bool:
        """Flush when the flush interval has passed since the last flush; return True if it did."""
        if self._unflushed and time.monotonic() - self._last_flush >= self.flush_interval_s:
            self.flush()
            return True
        return False

    def flush(self) -> None:
        """Close the current chunk and hand everything written so far to the operating system."""
        writer = self._writer()
        written = self._file.good if self._file is not None else 0
        try:
            writer.flush()
        except OSError as err:
            raise self._failed(err, 'writing', written) from None
        self.durable = sum(self.counts)
        self._last_flush = time.monotonic()
        self._unflushed = 0

    def summary(self) -> BagSummary:
        """Messages per topic and time span written so far."""
        return BagSummary(
            path=self.path,
            counts={t.name: n for t, n in zip(self.topics, self.counts)},
            start_ns=self.start_ns,
            end_ns=self.end_ns,
        )

    def metadata(self) -> dict[str, Any]:
        """Return the bag metadata map for what was written so far."""
        return bag_metadata(
            [self.mcap_path.name],
            self.topics,
            self.counts,
            self.start_ns,
            self.end_ns,
            self.custom_data,
        )

    def close(self) -> BagSummary:
        """Write the rosbag2 metadata record, the MCAP summary and footer, then metadata.yaml."""
        writer = self._writer()
        info = self.metadata()
        assert self._file is not None
        written = self._file.good
        try:
            writer.flush()
            self.durable = sum(self.counts)
            written = self._file.good
            writer.add_metadata('rosbag2', {'serialized_metadata': dump_yaml(info)})
            writer.finish()
            os.fsync(self._file.fileno())
        except OSError as err:
            raise self._failed(err, 'closing', written) from None
        self.abort()
        try:
            write_metadata_file(self.path, info)
        except OSError as err:
            raise BagIOError(
                f'writing {self.path / "metadata.yaml"} failed: {describe_os_error(err)} '
                f'(the MCAP file is complete)',
                err.errno,
            ) from None
        return self.summary()

    def abort(self) -> None:
        """Close the file without summary or metadata.yaml (what is flushed stays repairable)."""
        if self._file is not None:
            self._file.close()
        self._file = None
        self._mcap = None

    def discard(self) -> None:
        """Close and remove every file and folder open() created.

        For output that must not stay half-written.
        """
        self.abort()
        if not self._created:
            return
        files = [self.mcap_path, self.path / 'metadata.yaml', self.path / '.metadata.yaml.tmp']
        for path in files + [p for p in self._created if p not in files]:
            try:
                if path in files:
                    path.unlink(missing_ok=True)
                else:
                    path.rmdir()  # a folder open() created; only when empty
            except OSError:
                pass
        self._created = []

    def __enter__(self) -> BagWriter:
        """Open on entering the context."""
        self.open()
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        """Close normally, or abort when the block raised."""
        if exc_type is None:
            self.close()
        else:
            self.abort()
