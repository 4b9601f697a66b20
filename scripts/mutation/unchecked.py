# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Print the mutants of mutmut name globs still to judge (MUTATION_UNCHECKED=1).

Those without a result, those no test covered, and the survivors not explained in
equivalent.toml (tests written since their run may cover or kill them; mutmut keeps a result
until the mutated function changes). mutmut
reruns every mutant a name glob matches; this finishes a stopped run without redoing what it
judged. Reads the .meta files of build/mutation/mutants; prints one name per line.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import sys
import tomllib
from pathlib import Path

from report import EQUIVALENT, status  # scripts/mutation/report.py, beside this file


def unchecked(stage: Path, globs: list[str], equivalent: dict[str, str]) -> list[str]:
    """Return the names matching any of ``globs`` (all if none) that are unjudged or unexplained.

    Unjudged: no exit code, or no test covered it. Unexplained: survived, not in ``equivalent``.
    """
    names = []
    for meta in sorted((stage / 'mutants').rglob('*.py.meta')):
        codes = json.loads(meta.read_text())['exit_code_by_key']
        names += [
            name
            for name, code in codes.items()
            if (
                code is None
                or status(code) == 'no tests'
                or (status(code) == 'survived' and name not in equivalent)
            )
            and (not globs or any(fnmatch.fnmatch(name, g) for g in globs))
        ]
    return names


def main() -> int:
    """Print the unchecked mutants of the globs given."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--stage', type=Path, required=True)
    parser.add_argument('globs', nargs='*')
    args = parser.parse_args()
    equivalent = tomllib.loads(EQUIVALENT.read_text()) if EQUIVALENT.exists() else {}
    for name in unchecked(args.stage, args.globs, equivalent):
        print(name)  # none at all: no line (the script then runs nothing)
    return 0


if __name__ == '__main__':
    sys.exit(main())
