# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Error classes of the bag tooling and the one-line error reporting of its command-line tools."""

from __future__ import annotations

import sys
from typing import Callable, Optional, Sequence


class BagError(Exception):
    """Base class of every error the bag tooling raises on purpose."""

    #: Exit code of a command-line tool that ends with this error.
    exit_code = 1


class BagWriteError(BagError):
    """A bag could not be created or written (target exists, bad topic, closed writer)."""


class BagIOError(BagWriteError):
    """A write to a bag failed in the operating system (disk full, I/O error).

    ``errno`` says which.
    """

    def __init__(self, message: str, errno: Optional[int] = None) -> None:
        """Keep the one-line message and the OSError's errno."""
        super().__init__(message)
        self.errno = errno


class OutputLocationError(BagError):
    """An output location is refused before any work.

    It is inside or over an input bag, or not writable.
    """

    exit_code = 2


class BagReadError(BagError):
    """A path is not a readable rosbag2 bag (missing, not a bag, truncated, undecodable)."""


class DefinitionError(BagError):
    """A message definition could not be found or parsed."""


class RepairError(BagError):
    """A bag could not be repaired (nothing readable, target exists)."""


class AnalysisError(BagError):
    """A bag lacks what an analysis needs (topics, samples)."""


def run_cli(
    prog: str,
    main: Callable[[Optional[Sequence[str]]], int],
    argv: Optional[Sequence[str]] = None,
) -> int:
    """Run a tool's main, turning a BagError or an interrupt into a one-line message.

    The exit code of a BagError is its exit_code.
    """
    try:
        return main(argv)
    except BagError as err:
        print(f'{prog}: error: {err}', file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        print(f'{prog}: interrupted', file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 1
