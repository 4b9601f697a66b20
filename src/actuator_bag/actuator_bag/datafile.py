# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The MCAP data file as BagWriter writes it.

It is unbuffered, and cut back to its last complete write when one fails. The mcap Writer hands
the file whole groups of records (the header, a chunk, its message indexes, the summary), one
``write`` call each. ``DataFile`` remembers where the last complete call ended, so after a
failed write (ENOSPC, EIO, any OSError) the partial group can be cut off and the file ends on a
record boundary: bag_repair then recovers every chunk before it.

Test hook (documented in docs/bags.md#full-disk): with the environment variable
``ACTUATOR_BAG_TEST_FULL_AFTER_BYTES=N`` set, every data file opened behaves as a disk that is
full after N bytes: the bytes beyond are written to ``/dev/full``, so the failure is the
kernel's own ENOSPC. Only tests set it.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import Optional

#: Environment variable of the full-disk test hook (see the module docstring).
FULL_AFTER_ENV = 'ACTUATOR_BAG_TEST_FULL_AFTER_BYTES'
_DEV_FULL = '/dev/full'


class DataFile:
    """Write-only binary file with ``write``/``tell``/``flush``/``fileno``.

    It tracks its last good end.
    """

    def __init__(self, path: Path, full_after: Optional[int] = None) -> None:
        """Create ``path`` (it must not exist).

        After ``full_after`` bytes, writes fail with ENOSPC.
        """
        self.path = path
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o644)
        self.good = 0
        self._full_after = full_after

    def write(self, data: bytes) -> int:
        """Write all of ``data`` or raise OSError (the file is then longer than ``good``)."""
        view = memoryview(data)
        done = 0
        while done < len(view):
            room = len(view) - done
            if self._full_after is not None:
                room = min(room, self._full_after - (self.good + done))
                if room <= 0:
                    _write_to_dev_full(view[done:])
            done += os.write(self._fd, view[done : done + room])
        self.good += len(view)
        return len(view)

    def tell(self) -> int:
        """Bytes written completely so far."""
        return self.good

    def flush(self) -> None:
        """Nothing is buffered here."""

    def fileno(self) -> int:
        """Return the OS file descriptor."""
        return self._fd

    def cut_back(self) -> None:
        """Drop what a failed write left after the last complete one.

        Best effort: it needs no space.
        """
        try:
            os.ftruncate(self._fd, self.good)
        except OSError:
            pass

    def close(self) -> None:
        """Close the descriptor (idempotent)."""
        if self._fd >= 0:
            fd, self._fd = self._fd, -1
            os.close(fd)


def _write_to_dev_full(data: memoryview) -> None:
    """Write where the kernel answers ENOSPC (the test hook); raise that OSError."""
    fd = os.open(_DEV_FULL, os.O_WRONLY)
    try:
        os.write(fd, data)
    finally:
        os.close(fd)
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # not reached where /dev/full exists


def open_data_file(path: Path) -> DataFile:
    """Create a bag's data file, with the full-disk test hook applied when its variable is set."""
    limit = os.environ.get(FULL_AFTER_ENV, '').strip()
    return DataFile(path, int(limit) if limit else None)


def describe_os_error(err: OSError) -> str:
    """``No space left on device (ENOSPC)``: the reason with its errno name."""
    name = errno.errorcode.get(err.errno or 0, '')
    text = err.strerror or str(err)
    return f'{text} ({name})' if name else text
