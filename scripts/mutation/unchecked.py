# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Print the mutants of mutmut name globs that have no result yet (MUTATION_UNCHECKED=1).

mutmut reruns every mutant a name glob matches; this lets a stopped run be finished without
redoing what it judged. Reads the .meta files of build/mutation/mutants; one name per line.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import sys
from pathlib import Path


def unchecked(stage: Path, globs: list[str]) -> list[str]:
    """Return the names matching any of ``globs`` (all if none) whose exit code is unset."""
    names = []
    for meta in sorted((stage / 'mutants').rglob('*.py.meta')):
        codes = json.loads(meta.read_text())['exit_code_by_key']
        names += [
            name
            for name, code in codes.items()
            if code is None and (not globs or any(fnmatch.fnmatch(name, g) for g in globs))
        ]
    return names


def main() -> int:
    """Print the unchecked mutants of the globs given."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--stage', type=Path, required=True)
    parser.add_argument('globs', nargs='*')
    args = parser.parse_args()
    print('\n'.join(unchecked(args.stage, args.globs)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
