# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``bag_analyze``: the run table of one or more bags, the JSON and the paper's figures.

ros2 run actuator_analysis bag_analyze bags/A bags/B ... [--out DIR] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any, Callable, Optional, Sequence

from actuator_bag.errors import AnalysisError, BagError, run_cli
from actuator_bag.msgdefs import DefinitionSource, definition_roots
from actuator_bag.outputs import check_output_file, check_output_folder
from actuator_core.metrics import STEADY_STATE_START_S

from .analyze import analyze_run, load_run
from .analyze_table import format_table
from .figures import FIGURE_FILES, draw_figures
from .goals import format_goals, goal_reports


def build_parser() -> argparse.ArgumentParser:
    """Command-line interface of bag_analyze."""
    parser = argparse.ArgumentParser(
        prog='bag_analyze',
        description='Compare recorded runs: tracking, control effort, PPF bound compliance, '
        'estimation error and loop timing per bag, read offline from rosbag2/MCAP bags. '
        "Draws the paper's figures with --out.",
    )
    parser.add_argument(
        'bags', nargs='+', type=Path, metavar='BAG', help='bag folders (or .mcap files)'
    )
    parser.add_argument(
        '--out',
        type=Path,
        help='write position, tracking error, estimate and input figures (PNG) here '
        '(never inside an input bag)',
    )
    parser.add_argument(
        '--json',
        type=Path,
        help='write the figures of every bag as JSON to this file (never inside an input bag)',
    )
    parser.add_argument(
        '--steady-start',
        type=float,
        default=STEADY_STATE_START_S,
        metavar='SECONDS',
        help='start of the steady-state window after the run start [s] (default: %(default)s)',
    )
    add_msg_path(parser)
    parser.add_argument('-q', '--quiet', action='store_true', help='no progress lines')
    return parser


def add_msg_path(parser: argparse.ArgumentParser) -> None:
    """Add the --msg-path option of the bag tools: extra message definitions."""
    parser.add_argument(
        '--msg-path',
        type=Path,
        action='append',
        default=[],
        metavar='DIR',
        help='extra folder holding <pkg>/msg/<Type>.msg (searched first)',
    )


def _jsonable(value: Any) -> Any:
    """Replace non-finite floats (not valid JSON) with None, recursively."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


def write_json(path: Path, doc: Any) -> None:
    """Write ``doc`` as JSON (non-finite floats as null); BagError when the file cannot be."""
    try:
        path.write_text(
            json.dumps(_jsonable(doc), indent=2, default=str, allow_nan=False) + '\n',
            encoding='utf-8',
        )
    except OSError as err:
        raise BagError(f'cannot write {path}: {err.strerror}') from None


def write_figures(draw: Callable[[], list[Path]], folder: Path) -> None:
    """Draw the figures into ``folder`` and name them; BagError when they cannot be written."""
    try:
        paths = draw()
    except OSError as err:
        raise BagError(f'cannot write figures to {folder}: {err.strerror}') from None
    print(f'figures: {", ".join(str(p) for p in paths)}')


def _main(argv: Optional[Sequence[str]]) -> int:
    """Load, analyse, print, and write the optional JSON and figures."""
    args = build_parser().parse_args(argv)
    if not math.isfinite(args.steady_start) or args.steady_start < 0:
        raise AnalysisError(
            f'--steady-start must be a finite number >= 0, not {args.steady_start}'
        )
    # Output locations first: nothing is read or computed for a run whose results could not be
    # written.
    if args.json:
        check_output_file('--json', args.json, args.bags)
    if args.out:
        check_output_folder('--out', args.out, args.bags, FIGURE_FILES)
    source = DefinitionSource(definition_roots(args.msg_path))
    reports = []
    for bag in args.bags:
        run = load_run(bag, source, quiet=args.quiet)
        reports.append(analyze_run(run, args.steady_start))
    print(format_table(reports))
    goals = {r.run.name: goal_reports(r.run) for r in reports}
    for name, rows in goals.items():
        if rows:
            print(f'\ngoals of {name}:\n{format_goals(rows)}')
    if args.json:
        write_json(
            args.json,
            [{**r.as_dict(), 'goals': [g.as_dict() for g in goals[r.run.name]]} for r in reports],
        )
    if args.out:
        write_figures(lambda: draw_figures([r.run for r in reports], args.out), args.out)
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``bag_analyze``."""
    return run_cli('bag_analyze', _main, argv)


if __name__ == '__main__':
    raise SystemExit(main())
