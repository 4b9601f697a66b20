# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""In-process recording's wire (ROS-free): frames from a loop's process to its bag writer.

A composed loop that records in-process (actuator_bag.tap) hands each message it publishes,
already serialized, to a ``FrameSpool``; the spool batches them and writes them to a pipe; a
writer process (``python -m actuator_bag.spool --output BAG``, ``main`` here) reads the frames
from its standard input and writes the bag with the recorder's ``BagWriter``. The loop's
process pays a list append per message and a pipe write per batch; the MCAP writing, a
Python library's work, runs on another CPU and never takes the loop's GIL. A full pipe
blocks the loop (sim time only: a lockstep has no deadline), so nothing is dropped.

Frames: a ``HEADER`` (topic index, log time [ns], length) and that many bytes. Index
``TOPIC_FRAME`` announces a topic: its payload is JSON with the index, name, type and offered
QoS profiles, sent before the topic's first message.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import struct
import sys
from pathlib import Path
from typing import BinaryIO, Iterator, Optional, Sequence

from .bag_format import (
    DEFAULT_CHUNK_SIZE,
    DEFAULT_FLUSH_INTERVAL_S,
    BagWriter,
    TopicSpec,
    topic_spec,
)
from .bag_qos import QosProfile
from .errors import BagError, BagIOError
from .msgdefs import DefinitionSource

#: A frame's header: topic index (uint16), log time [ns] (int64), payload length (uint32).
HEADER = struct.Struct('<HqI')
#: The index of a frame that announces a topic (JSON payload) instead of carrying a message.
TOPIC_FRAME = 0xFFFF
#: Bytes a spool gathers before it writes them to the pipe: about 100 samples of the loop's six
#: topics, so a pipe write (a system call that releases the GIL) every 0.1 s of sim time.
BATCH_BYTES = 64 * 1024
#: The pipe's capacity the spool asks Linux for (F_SETPIPE_SZ): 16 batches of slack before a
#: slow writer holds the loop up.
PIPE_BYTES = 1 << 20
_F_SETPIPE_SZ, _F_GETPIPE_SZ = 1031, 1032  # fcntl.h (Linux)
#: Custom data of a bag written in-process (metadata.yaml, as the recorder writes its own).
CUSTOM_DATA = {
    'recorder': 'actuator_bag in-process recording (the loop container publishing, '
    'actuator_bag.spool writing)',
    'log_time': 'publish time on the sim clock (the newest /clock the process published)',
    'publish_time': 'the log time',
}


class SpoolError(BagError):
    """The writer process is gone: what the spool still had could not be handed over."""


class FrameSpool:
    """Batches frames and writes them to a file descriptor (the writer process's stdin)."""

    def __init__(self, fd: int, batch_bytes: int = BATCH_BYTES) -> None:
        """Write frames to ``fd`` (blocking) in batches of about ``batch_bytes``."""
        self.fd = fd
        self.batch_bytes = batch_bytes
        self.batch: list[bytes | bytearray] = []
        self.pending = 0
        self.frames = 0  # message frames accepted
        self.sent = 0  # message frames handed to the writer (all but the batch in hand)

    def add_topic(self, index: int, name: str, msgtype: str, qos: Sequence[QosProfile]) -> None:
        """Announce topic ``index`` before its first message, at once (the bag opens then)."""
        payload = json.dumps(
            {'index': index, 'name': name, 'type': msgtype, 'qos': [q.as_dict() for q in qos]}
        ).encode()
        self.batch += (HEADER.pack(TOPIC_FRAME, 0, len(payload)), payload)
        self.pending += HEADER.size + len(payload)
        self.flush()

    def add(self, index: int, log_ns: int, data: bytes | bytearray) -> None:
        """One serialized message of topic ``index``, logged at ``log_ns``."""
        self.batch += (HEADER.pack(index, log_ns, len(data)), data)
        self.pending += HEADER.size + len(data)
        self.frames += 1
        if self.pending >= self.batch_bytes:
            self.flush()

    def flush(self) -> None:
        """Write what is gathered; SpoolError when the writer is gone (the batch is kept)."""
        if not self.batch:
            return
        data = memoryview(b''.join(self.batch))
        try:
            while data:
                data = data[os.write(self.fd, data) :]
        except OSError as err:
            raise SpoolError(
                f'the bag writer took no more ({err.strerror}): '
                f'{self.frames - self.sent} messages not recorded'
            ) from None
        self.batch.clear()
        self.pending = 0
        self.sent = self.frames


def grow_pipe(fd: int, size: int = PIPE_BYTES) -> int:
    """Ask for a pipe of ``size`` bytes; return the size Linux gave (its limit may be lower)."""
    import fcntl

    try:
        return fcntl.fcntl(fd, _F_SETPIPE_SZ, size)
    except OSError:
        return fcntl.fcntl(fd, _F_GETPIPE_SZ)  # keep what it is


def read_frames(stream: BinaryIO, read_size: int = 1 << 20) -> Iterator[tuple[int, int, bytes]]:
    """Yield (index, log time, payload) per frame until the end of ``stream``.

    BagError when the stream ends inside a frame (the sender died mid-write).
    """
    buffer = b''
    while True:
        chunk = stream.read(read_size)
        if not chunk:
            break
        buffer = buffer + chunk if buffer else chunk
        pos, end = 0, len(buffer)
        while end - pos >= HEADER.size:
            index, log_ns, length = HEADER.unpack_from(buffer, pos)
            start = pos + HEADER.size
            if end - start < length:
                break
            yield index, log_ns, buffer[start : start + length]
            pos = start + length
        buffer = buffer[pos:]
    if buffer:
        raise BagError(f'the recording ended inside a frame ({len(buffer)} bytes cut off)')


def write_bag(
    stream: BinaryIO,
    output: Path,
    chunk_size: int = DEFAULT_CHUNK_SIZE,
    flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S,
) -> Optional[BagWriter]:
    """Write the frames of ``stream`` into the bag folder ``output``; return the closed writer.

    The bag is created at the first frame: a stream that ends with none (the loop's process
    ended before building its nodes) leaves nothing, and None is returned. BagIOError (disk
    full ...): the file is cut back to its last complete chunk, as the recorder does; BagError:
    a frame for a topic never announced, or a cut-off stream (what came before is written and
    the bag closed first).
    """
    writer: Optional[BagWriter] = None
    source = DefinitionSource()
    specs: dict[int, TopicSpec] = {}
    handles: dict[int, int] = {}
    try:
        for index, log_ns, payload in read_frames(stream):
            if writer is None:
                writer = BagWriter(
                    output,
                    chunk_size=chunk_size,
                    flush_interval_s=flush_interval_s,
                    custom_data=CUSTOM_DATA,
                )
                writer.open()
            if index == TOPIC_FRAME:
                topic = json.loads(payload)
                specs[topic['index']] = topic_spec(
                    topic['name'],
                    topic['type'],
                    source,
                    [QosProfile.from_dict(q) for q in topic['qos']],
                )
                continue
            handle = handles.get(index)
            if handle is None:
                if index not in specs:
                    raise BagError(f'a message of topic {index}, which was never announced')
                handle = handles[index] = writer.add_topic(specs[index])
            writer.write(handle, log_ns, payload)
        if writer is not None:
            writer.close()
    except BagIOError as err:  # the writer is closed, its file cut back to a complete chunk
        assert writer is not None  # only the writer raises it
        lost = sum(writer.counts) - writer.durable
        raise BagIOError(
            f'{err}; {writer.durable} messages are on disk, {lost} received ones were lost',
            err.errno,
        ) from None
    except BagError:
        if writer is not None and writer.is_open:
            writer.close()
        raise
    return writer


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of the writer process: frames on stdin -> the bag; 0, or 1 with one line."""
    parser = argparse.ArgumentParser(
        prog='actuator_bag.spool', description="Write a loop container's recording into a bag."
    )
    parser.add_argument('--output', required=True, type=Path, help='bag folder to create')
    parser.add_argument('--chunk-size', type=int, default=DEFAULT_CHUNK_SIZE)
    parser.add_argument('--flush-interval', type=float, default=DEFAULT_FLUSH_INTERVAL_S)
    args = parser.parse_args(argv)
    # The loop's process ends the recording by closing the pipe; a Ctrl-C reaches this process
    # too (same process group) and must not cut the bag short.
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
    try:
        writer = write_bag(sys.stdin.buffer, args.output, args.chunk_size, args.flush_interval)
    except BagIOError as err:
        print(
            f'recorder: {err}; recording stopped: the bag has no metadata.yaml: '
            f'run bag_repair {args.output}',
            file=sys.stderr,
            flush=True,
        )
        return 1
    except BagError as err:
        print(f'recorder: {err}', file=sys.stderr, flush=True)
        return 1
    if writer is None:
        print(
            "recorder: nothing to record (the loop's process sent nothing): no bag written",
            flush=True,
        )
    else:
        print(f'recorder: wrote {writer.summary().line()} (in-process recording)', flush=True)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
