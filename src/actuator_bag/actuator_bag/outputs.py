# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Where the bag tools may write, checked before any work: never inside or over a source bag.

A source bag folder (an input folder, or the folder of an input .mcap file when it is a
rosbag2 folder: it holds metadata.yaml or the file is named ``<folder>_<n>.mcap``) may not be
an output or hold one; no output may be, or be a link to, an input file; the folder an output
goes into (or its nearest existing ancestor, for a folder to create) must be a writable folder.
Every refusal is an OutputLocationError (one line, exit code 2).
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path
from typing import Iterable, Sequence

from .errors import OutputLocationError


def _is_bag_folder_of(file: Path) -> bool:
    """Tell whether the folder of an MCAP file is a rosbag2 folder.

    It is one when it holds metadata.yaml, or when the file is named ``<folder>_<n>.mcap``.
    """
    folder = file.parent
    return (folder / 'metadata.yaml').is_file() or re.fullmatch(
        re.escape(folder.name) + r'_\d+\.mcap', file.name
    ) is not None


def source_folders(inputs: Iterable[Path]) -> list[Path]:
    """Return the resolved bag folders of the inputs, which no output may be inside of."""
    folders = []
    for path in inputs:
        real = Path(path).resolve()
        if real.is_dir():
            folders.append(real)
        elif real.is_file() and _is_bag_folder_of(real):
            folders.append(real.parent)
    return folders


def source_files(inputs: Iterable[Path]) -> list[Path]:
    """Return the resolved input files, which no output may overwrite.

    An input folder's files are included.
    """
    files: list[Path] = []
    for path in inputs:
        real = Path(path).resolve()
        if real.is_dir():
            files.extend(p.resolve() for p in real.iterdir() if p.is_file())
        elif real.exists():
            files.append(real)
    return files


def _same_file(a: Path, b: Path) -> bool:
    """Tell whether both exist and are the same file (hard links included)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def writable_folder(folder: Path) -> bool:
    """Tell whether a file can be created in ``folder``.

    Checked by creating and removing one: root ignores modes.
    """
    if not folder.is_dir() or not os.access(folder, os.W_OK | os.X_OK):
        return False
    try:
        fd, name = tempfile.mkstemp(prefix='.bag-write-check-', dir=folder)
    except OSError:
        return False
    os.close(fd)
    os.unlink(name)
    return True


def _nearest_existing(path: Path) -> Path:
    """``path`` or its nearest ancestor that exists."""
    for candidate in (path, *path.parents):
        if candidate.exists():
            return candidate
    return Path('/')


def _check_not_source(label: str, out: Path, real: Path, inputs: Sequence[Path]) -> None:
    """Refuse an output inside (or equal to) a source bag folder, or one that is an input file."""
    for file in source_files(inputs):
        if real == file or _same_file(real, file):
            raise OutputLocationError(f'{label} {out} would overwrite the input file {file}')
    for folder in source_folders(inputs):
        if real == folder or folder in real.parents:
            raise OutputLocationError(
                f'{label} {out} is inside the source bag {folder}: tools never write '
                'into a bag they read; choose a location outside it'
            )


def check_output_file(
    label: str, out: Path, inputs: Sequence[Path], created: Iterable[Path] = ()
) -> None:
    """Check a file to be written (``--json F``).

    Not a source, not a folder, its folder writable or in ``created``.
    """
    real = Path(out).resolve()
    _check_not_source(label, out, real, inputs)
    if real.is_dir():
        raise OutputLocationError(f'{label} {out} is a folder, not a file')
    if real.parent in {Path(c).resolve() for c in created}:
        return
    if not writable_folder(real.parent):
        what = 'is not writable' if real.parent.is_dir() else 'does not exist or is not a folder'
        raise OutputLocationError(f'{label} {out}: folder {real.parent} {what}')


def check_output_folder(
    label: str, out: Path, inputs: Sequence[Path], names: Iterable[str] = ()
) -> None:
    """Check a folder to be written (created if missing) with files ``names``.

    Not a source, creatable.
    """
    real = Path(out).resolve()
    _check_not_source(label, out, real, inputs)
    for name in names:
        _check_not_source(label, out / name, real / name, inputs)
    if real.exists() and not real.is_dir():
        raise OutputLocationError(f'{label} {out} exists and is not a folder')
    base = _nearest_existing(real)
    if not base.is_dir() or not writable_folder(base):
        raise OutputLocationError(f'{label} {out}: {base} is not a writable folder')
