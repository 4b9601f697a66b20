# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Write docs/mutation-report.md from mutmut's results in build/mutation (scripts/mutation.sh).

Per module: the SHA-256 of its code when it was mutated (first 12 hex digits; a unit test,
tests/test_mutation_report.py, fails when a module's source no longer matches its row, so a
stale score cannot be quoted), killed, survived, timeout, no tests, not checked, and the score
killed / (killed + survived + no tests), timeouts counted as killed (the test run did not pass).
Every survivor is listed with its diff; those explained in scripts/mutation/equivalent.toml
carry the reason and are left out of the "score without equivalents".
"""

from __future__ import annotations

import argparse
import ast
import hashlib
import json
import os
import re
import subprocess
import sys
import tomllib
from collections import Counter
from importlib.metadata import version
from pathlib import Path

KILLED = {1: 'killed', 3: 'killed', 36: 'timeout', 24: 'timeout', -24: 'timeout', 152: 'timeout'}
STATUS = {0: 'survived', 5: 'no tests', 33: 'no tests', None: 'not checked', 34: 'skipped'}
#: The modules the issue sets a target for, and the target share killed.
TARGETS = {
    'actuator_core/pairing.py': 0.95,
    'actuator_core/assembly.py': 0.95,
    'actuator_core/timebase.py': 0.95,
    'actuator_core/gate.py': 0.95,
}
CORE_TARGET = 0.85
EQUIVALENT = Path(__file__).resolve().parent / 'equivalent.toml'
ROOT = Path(__file__).resolve().parents[2]
#: The columns before the counts: the module and its source's hash.
LEAD = 2
#: The source cell of a row whose module changed since its run (its score is withheld).
STALE = 'stale'


def source_hash(module: str, root: Path = ROOT) -> str:
    """Return the first 12 hex digits of the SHA-256 of a module's code (e.g. a/gate.py).

    Of its syntax tree without docstrings: what mutmut mutates, so an edit of a comment or a
    docstring leaves the score standing and any change of the code does not.
    """
    package = module.split('/')[0]
    tree = ast.parse((root / 'src' / package / module).read_text())
    for node in ast.walk(tree):
        body = getattr(node, 'body', None)
        if (
            isinstance(body, list)
            and body
            and isinstance(body[0], ast.Expr)
            and isinstance(body[0].value, ast.Constant)
            and isinstance(body[0].value.value, str)
        ):
            node.body = body[1:] or [ast.Pass()]
    return hashlib.sha256(ast.dump(tree).encode()).hexdigest()[:12]


def status(code) -> str:
    """Return mutmut's verdict for one exit code (as mutmut's own table says)."""
    return KILLED.get(code) or STATUS.get(code) or f'suspicious ({code})'


def load_results(stage: Path) -> dict[str, dict[str, str]]:
    """Return {module path: {mutant name: status}} from the .meta files of a mutmut run."""
    results = {}
    for meta in sorted((stage / 'mutants').rglob('*.py.meta')):
        module = str(meta.relative_to(stage / 'mutants'))[: -len('.meta')]
        codes = json.loads(meta.read_text())['exit_code_by_key']
        if codes:
            results[module] = {name: status(code) for name, code in codes.items()}
    return results


def diff(stage: Path, name: str) -> str:
    """Return the diff of one mutant (``mutmut show``), without its header line."""
    out = subprocess.run(
        [sys.executable, '-m', 'mutmut', 'show', name],
        cwd=stage,
        capture_output=True,
        text=True,
        check=False,
    ).stdout
    return '\n'.join(line for line in out.splitlines()[1:] if not line.startswith(('---', '+++')))


def recheck(stage: Path, name: str, tests: list[str]) -> bool:
    """Run ``tests`` (paths under the repository) on one mutant; True when they kill it.

    As mutmut runs a mutant: in mutants/ (the mutated copy first on sys.path), with
    MUTANT_UNDER_TEST naming it. For survivors of a run made before those tests existed; mutmut
    itself records them at its next run of these mutants.
    """
    mutants = stage / 'mutants'
    env = dict(os.environ, MUTANT_UNDER_TEST=name)
    env['PYTHONPATH'] = os.pathsep.join([str(mutants), env.get('PYTHONPATH', '')])
    proc = subprocess.run(
        [sys.executable, '-m', 'pytest', '-x', '-q', '-p', 'no:cacheprovider', *tests],
        cwd=mutants,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    return proc.returncode == 1


def score(counts: Counter) -> float:
    """Return killed (timeouts included) over the mutants a test run judged; NaN if none."""
    killed = counts['killed'] + counts['timeout']
    judged = killed + counts['survived'] + counts['no tests']
    return killed / judged if judged else float('nan')


def _pct(x: float) -> str:
    """Return a share as a percentage, or a dash when nothing was judged."""
    return '—' if x != x else f'{x:.1%}'


#: The preamble lines every report repeats, left out of the list of earlier runs.
BOILERPLATE = (
    '`scripts/mutation/pyproject.toml`',
    'Score = killed',
    'leaves out the survivors',
    'Not checked: mutants',
    'Rows marked (earlier)',
    'Earlier runs',
)


def earlier_runs(preamble: list[str]) -> list[str]:
    """Return the runs a report's preamble names (its own first), one Markdown item each.

    Reports kept rows of earlier ones and quoted their preambles, nested; this flattens them:
    each run's command, time and load, and its note on rechecked survivors, newest first.
    """
    runs: list[list[str]] = []
    for line in preamble:
        text = line.lstrip('> ').strip()
        if text.startswith('- '):  # an item of a flat list written by this function
            runs.append([text[2:]])
        elif text.startswith('Command:'):
            runs.append([text.split(' (scripts/mutation.sh')[0].strip()])
        elif runs and text and not text.startswith(BOILERPLATE):
            runs[-1].append(text)
    items = []
    for run in runs:
        item = ' '.join(run).replace(' on a shared 2-core machine (', ' (').strip()
        if item not in items:
            items.append(item)
    return [f'- {item}' for item in items]


def earlier_report(text: str) -> tuple[list[str], dict[str, str], dict[str, list[str]]]:
    """Split a report of this script: its runs, table rows and survivor sections by module."""
    head, _, survivors = text.partition('\n## Surviving mutants')
    preamble = earlier_runs([x for x in head.split('\n|', 1)[0].splitlines()[2:] if x.strip()])
    rows = {}
    for line in head.splitlines():
        cells = [c.strip() for c in line.strip('|').split('|')]
        module = cells[0].removesuffix(' (earlier)')  # kept by that report from one before
        if line.startswith('| ') and module.endswith('.py'):
            rows[module] = line.replace(f'| {cells[0]} |', f'| {module} |', 1)
    sections: dict[str, list[str]] = {}
    for block in survivors.split('\n### ')[1:]:
        name = block.split('`')[1]
        module = re.split(r'\.x[_ǁ]', name)[0].replace('.', '/') + '.py'
        sections.setdefault(module, []).append('### ' + block.rstrip('\n') + '\n')
    return preamble, rows, sections


def _judged(row: str) -> int:
    """Return how many mutants a report row says were judged (killed, timeout, survived, none)."""
    cells = [c.strip() for c in row.strip('|').split('|')]
    return sum(int(c) for c in cells[LEAD + 1 : LEAD + 5])


def render(
    stage: Path,
    command: str,
    equivalent: dict[str, str],
    recheck_tests: list[str],
    earlier: str = '',
) -> str:
    """Return the report's Markdown.

    ``earlier``: the previous report; the modules this run did not reach keep its row and
    survivors, marked as from that run.
    """
    results = load_results(stage)
    preamble, kept_rows, kept_sections = earlier_report(earlier) if earlier else ([], {}, {})
    kept = {
        m
        for m, by_name in results.items()
        if m in kept_rows
        and all(v == 'not checked' for v in by_name.values())
        and _judged(kept_rows[m])  # the earlier run had checked it
    }
    names = [Path(t).name for t in recheck_tests]
    rechecked = {}
    if recheck_tests:
        for by_name in results.values():
            for name, verdict in by_name.items():
                if verdict == 'survived' and name not in equivalent:
                    if recheck(stage, name, recheck_tests):
                        by_name[name] = 'killed'
                        rechecked[name] = True
    load = os.getloadavg()
    lines = [
        '# Mutation score of the ROS-free core',
        '',
        f'Command: `{command}` (scripts/mutation.sh; mutmut {version("mutmut")}, configuration',
        '`scripts/mutation/pyproject.toml`: what is mutated and which unit tests run). Not in CI.',
        'Run on a shared 2-core machine (load average at the end '
        f'{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f}); each row names its code by hash.',
        '',
        'Score = killed / (killed + survived + no tests); a timeout counts as killed. "w/o eq."',
        'leaves out the survivors explained as equivalent (scripts/mutation/equivalent.toml).',
        'Not checked: mutants the run did not reach (it was stopped; see the command).',
        *(
            [
                f'{len(rechecked)} survivors of the run are counted killed by tests written after',
                f'it (rechecked with MUTANT_UNDER_TEST on: {", ".join(names)}):',
                ', '.join(f'`{n.rsplit(".", 1)[-1]}`' for n in sorted(rechecked)) + '.',
            ]
            if rechecked
            else []
        ),
        '',
        '| module | source | mutants | killed | timeout | survived | no tests | not checked |'
        ' score | w/o eq. | target |',
        '|---|---|---|---|---|---|---|---|---|---|---|',
    ]
    if kept:
        lines[-2:-2] = [
            f'Rows marked (earlier) and their survivors are from earlier runs, for the modules '
            f'this run did not reach ({len(kept)}). Earlier runs, newest first:',
            '',
            *preamble,
            '',
        ]
    survivors = []
    kept_blocks = []
    total = Counter()
    stale = 0
    for module, by_name in results.items():
        if module in kept:
            cells = [c.strip() for c in kept_rows[module].strip('|').split('|')]
            if cells[1] != source_hash(module):  # changed since that run: its score is withheld
                cells[1], cells[LEAD + 6], cells[LEAD + 7] = STALE, '—', '—'
            stale += cells[1] == STALE
            cells[0] = f'{module} (earlier)'
            lines.append('| ' + ' | '.join(cells) + ' |')
            keys = ('mutants', 'killed', 'timeout', 'survived', 'no tests', 'not checked')
            total += Counter(dict(zip(keys[1:], (int(c) for c in cells[LEAD + 1 : LEAD + 6]))))
            kept_blocks += kept_sections.get(module, [])
            continue
        counts = Counter(by_name.values())
        total += counts
        eq = sum(1 for n, s in by_name.items() if s == 'survived' and n in equivalent)
        adjusted = counts.copy()
        adjusted['survived'] -= eq
        target = TARGETS.get(module, CORE_TARGET)
        lines.append(
            f'| {module} | {source_hash(module)} | {len(by_name)} | {counts["killed"]} | '
            f'{counts["timeout"]} | '
            f'{counts["survived"]} | {counts["no tests"]} | {counts["not checked"]} | '
            f'{_pct(score(counts))} | {_pct(score(adjusted))} | {target:.0%} |'
        )
        survivors += [(module, n) for n, s in by_name.items() if s in ('survived', 'no tests')]
    lines.append(
        f'| **all** | | {sum(total.values())} | {total["killed"]} | {total["timeout"]} | '
        f'{total["survived"]} | {total["no tests"]} | {total["not checked"]} | '
        f'{"—" if stale else _pct(score(total))} | | |'
    )
    lines += ['', f'## Surviving mutants ({len(survivors) + len(kept_blocks)})', '']
    lines += kept_blocks
    for module, name in survivors:
        reason = equivalent.get(name)
        lines.append(f'### `{name}`' + (' (equivalent)' if reason else ''))
        if reason:
            lines += ['', reason]
        lines += ['', '```diff', diff(stage, name), '```', '']
    return '\n'.join(lines) + '\n'


def mark_stale(text: str, root: Path = ROOT) -> str:
    """Return a report with every row whose module's code changed since its run marked stale.

    Its score and score without equivalents are withheld ('—'), and so is the total's: a code
    change since the run makes a quoted score untrue until the module is mutated again.
    """
    lines, stale = [], False
    for line in text.split('\n'):
        cells = [c.strip() for c in line.strip('|').split('|')]
        module = cells[0].removesuffix(' (earlier)') if line.startswith('| ') else ''
        if module.endswith('.py') and cells[1] not in (STALE, source_hash(module, root)):
            cells[1], cells[LEAD + 6], cells[LEAD + 7] = STALE, '—', '—'
            line = '| ' + ' | '.join(cells) + ' |'
        stale = stale or (module.endswith('.py') and cells[1] == STALE)
        lines.append(line)
    if stale:
        lines = [_withhold_total(line) if line.startswith('| **all**') else line for line in lines]
    return '\n'.join(lines)


def _withhold_total(line: str) -> str:
    """Return the total's row with its score withheld."""
    cells = [c.strip() for c in line.strip('|').split('|')]
    cells[LEAD + 6] = '—'
    return '| ' + ' | '.join(cells) + ' |'


def main() -> int:
    """Write the report of the mutmut results in --stage to --out (or mark its stale rows)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        '--mark-stale',
        type=Path,
        metavar='REPORT',
        help='only mark the rows of REPORT whose module changed since its run stale, in place',
    )
    parser.add_argument('--stage', type=Path)
    parser.add_argument('--out', type=Path)
    parser.add_argument('--command', default='make mutation')
    parser.add_argument(
        '--recheck',
        nargs='*',
        default=[],
        metavar='TEST',
        help='test files (repository paths) to run on each survivor (tests newer than the run)',
    )
    parser.add_argument(
        '--keep-earlier',
        action='store_true',
        help='keep the rows of --out for the modules this run did not reach (a partial run)',
    )
    args = parser.parse_args()
    if args.mark_stale:
        args.mark_stale.write_text(mark_stale(args.mark_stale.read_text()))
        return 0
    if args.stage is None or args.out is None:
        parser.error('--stage and --out are required (or --mark-stale REPORT)')
    equivalent = tomllib.loads(EQUIVALENT.read_text()) if EQUIVALENT.exists() else {}
    tests = [str(Path(t).resolve()) for t in args.recheck]
    earlier = args.out.read_text() if args.keep_earlier and args.out.exists() else ''
    args.out.write_text(render(args.stage, args.command, equivalent, tests, earlier))
    print(f'[mutation] report: {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
