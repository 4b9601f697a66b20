# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Opening bags for reading with rosbags, with one-line errors for every kind of bad input."""

from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator, Optional, Sequence

from rosbags.interfaces import Connection, MessageDefinitionFormat
from rosbags.rosbag2 import Reader, ReaderError
from rosbags.typesys import get_types_from_msg
from rosbags.typesys.base import TypesysError
from rosbags.typesys.store import Typestore

from .errors import BagReadError, DefinitionError
from .msgdefs import DefinitionSource


def check_bag_path(path: os.PathLike | str) -> Path:
    """Return the path if it looks like a rosbag2 bag; else BagReadError.

    A bag is a folder with metadata.yaml, or an .mcap file.
    """
    path = Path(path)
    if not path.exists():
        raise BagReadError(f'{path}: no such bag (the path does not exist)')
    if path.is_dir():
        if (path / 'metadata.yaml').is_file():
            return path
        if any(path.glob('*.mcap')):
            raise BagReadError(
                f'{path}: no metadata.yaml, so the recording was interrupted; '
                f'run: bag_repair {path}'
            )
        raise BagReadError(f'{path}: not a rosbag2 bag (a folder without metadata.yaml)')
    if path.suffix not in ('.mcap', '.db3'):
        raise BagReadError(f'{path}: not a bag (expected a bag folder or a .mcap file)')
    return path


def _describe(path: Path, err: BaseException) -> str:
    """One-line reason for a rosbags failure, with a hint where one helps."""
    text = ' '.join(str(err).split()) or type(err).__name__
    if 'magic' in text.lower() or 'footer' in text.lower() or 'unexpected end' in text.lower():
        return f'{path}: truncated or damaged bag file ({text}); try: bag_repair {path}'
    return f'{path}: unreadable bag ({text})'


@contextmanager
def open_bag(path: os.PathLike | str) -> Iterator[Reader]:
    """Open a bag with rosbags' Reader; every failure to open or read becomes a BagReadError."""
    path = check_bag_path(path)
    try:
        reader = Reader(path)
        reader.open()
    except (ReaderError, OSError, ValueError, KeyError, TypeError, AssertionError) as err:
        raise BagReadError(_describe(path, err)) from None
    try:
        yield reader
    except (ReaderError, OSError, AssertionError) as err:
        raise BagReadError(_describe(path, err)) from None
    finally:
        try:
            reader.close()
        except (ReaderError, OSError, AssertionError):
            pass


def bag_typestore(
    reader: Reader,
    source: Optional[DefinitionSource] = None,
    connections: Optional[Sequence[Connection]] = None,
) -> Typestore:
    """Typestore for a bag's ``connections`` (default: all).

    Installed .msg definitions first, the bag's embedded definitions for the rest.
    """
    source = source or DefinitionSource()
    store = source.typestore()
    for conn in reader.connections if connections is None else connections:
        if conn.msgtype in store.fielddefs:
            continue
        try:
            store = source.typestore([conn.msgtype])
            continue
        except DefinitionError:
            pass
        if conn.msgdef.format != MessageDefinitionFormat.MSG or not conn.msgdef.data:
            raise BagReadError(f'no definition of {conn.msgtype} installed or in the bag')
        try:
            store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
        except TypesysError as err:
            raise BagReadError(
                f'cannot use the definition of {conn.msgtype} in the bag: {err}'
            ) from None
    return store


def find_topic(
    connections: Sequence[Connection], msgtype: str, preferred_suffix: str
) -> Optional[Connection]:
    """Return the connection of a type whose topic ends with ``preferred_suffix``.

    Else the only one of that type.
    """
    of_type = [c for c in connections if c.msgtype == msgtype]
    for conn in of_type:
        if conn.topic == preferred_suffix or conn.topic.endswith(
            '/' + preferred_suffix.lstrip('/')
        ):
            return conn
    return of_type[0] if len(of_type) == 1 else None


def topic_names(connections: Iterable[Connection]) -> str:
    """Comma-separated ``topic [type]`` list for messages."""
    return ', '.join(f'{c.topic} [{c.msgtype}]' for c in connections) or 'none'
