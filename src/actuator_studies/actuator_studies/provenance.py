# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Where a study's figures come from: commit, lock files, library versions, command line, seeds.

Recorded in study.json (sweeps) and design.json (designs), so a figure can be traced back to
the code and the pinned environment that produced it. The commit is that of the git work tree
holding this package's source (``dirty`` when it has uncommitted changes); the lock hash is
the SHA-256 over requirements/*.lock of that tree, in name order.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import platform
import subprocess
import sys
from pathlib import Path

#: Distributions whose versions a study records.
LIBRARIES = ('numpy', 'ray', 'optuna', 'pyarrow', 'scipy')


def _git(args: list[str], cwd: Path) -> str | None:
    """Output of a git command in ``cwd`` (None when git or the repository is missing)."""
    try:
        out = subprocess.run(
            ['git', *args], cwd=cwd, capture_output=True, text=True, timeout=10, check=True
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


def source_tree() -> Path | None:
    """Top of the git work tree that holds this package's source (None outside one)."""
    here = Path(__file__).resolve().parent
    top = _git(['rev-parse', '--show-toplevel'], here)
    return Path(top) if top else None


def lock_hash(tree: Path | None) -> str | None:
    """SHA-256 of the requirements/*.lock files of ``tree``, in name order."""
    if tree is None or not (tree / 'requirements').is_dir():
        return None
    digest = hashlib.sha256()
    for lock in sorted((tree / 'requirements').glob('*.lock')):
        digest.update(lock.name.encode() + b'\0' + lock.read_bytes())
    return digest.hexdigest()


def library_versions() -> dict[str, str | None]:
    """Installed versions of LIBRARIES and of Python."""
    versions: dict[str, str | None] = {'python': platform.python_version()}
    for name in LIBRARIES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def provenance(seeds: dict) -> dict:
    """Commit, dirty flag, lock hash, library versions, command line and the given seeds."""
    tree = source_tree()
    commit = _git(['rev-parse', 'HEAD'], tree) if tree else None
    dirty = bool(_git(['status', '--porcelain', '--untracked-files=no'], tree)) if tree else None
    return {
        'commit': commit,
        'dirty': dirty,
        'lock_sha256': lock_hash(tree),
        'libraries': library_versions(),
        'command_line': [Path(sys.argv[0]).name, *sys.argv[1:]],
        'seeds': seeds,
    }
