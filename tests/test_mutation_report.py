# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""scripts/mutation/report.py: a partial run keeps the earlier report's rows of the rest."""

import importlib.util
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _report_module():
    spec = importlib.util.spec_from_file_location(
        'mutation_report', ROOT / 'scripts' / 'mutation' / 'report.py'
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _stage(tmp_path: Path, codes: dict[str, dict[str, object]]) -> Path:
    """Write a mutmut stage: one .meta file per module, {module path: {mutant: exit code}}."""
    for module, by_name in codes.items():
        meta = tmp_path / 'mutants' / f'{module}.meta'
        meta.parent.mkdir(parents=True, exist_ok=True)
        meta.write_text(json.dumps({'exit_code_by_key': by_name}))
    return tmp_path


EARLIER = """# Mutation score of the ROS-free core

Command: `make mutation ARGS='actuator_core.gate*'` (scripts/mutation.sh)
Written 2026-12-01 22:07 UTC.

| module | source | mutants | killed | timeout | survived | none | unchkd | score | eq. | target |
|---|---|---|---|---|---|---|---|---|---|---|
| actuator_controller/laws.py | 000000000000 | 2 | 0 | 0 | 0 | 0 | 2 | — | — | 85% |
| actuator_core/gate.py | GATE_HASH | 3 | 2 | 0 | 1 | 0 | 0 | 66.7% | 66.7% | 95% |
| **all** | | 5 | 2 | 0 | 1 | 0 | 2 | 66.7% | | |

## Surviving mutants (1)

### `actuator_core.gate.xǁCommandGateǁoffer__mutmut_3`

```diff
-a
+b
```
"""


def test_a_partial_run_keeps_the_rows_and_survivors_of_the_modules_it_did_not_reach(tmp_path):
    report = _report_module()
    gate_hash = report.source_hash('actuator_core/gate.py')
    laws_hash = report.source_hash('actuator_controller/laws.py')
    stage = _stage(
        tmp_path,
        {
            'actuator_controller/laws.py': {'laws.x_a__mutmut_1': 1, 'laws.x_a__mutmut_2': 1},
            'actuator_core/gate.py': {f'actuator_core.gate.x__mutmut_{i}': None for i in range(3)},
        },
    )
    earlier = EARLIER.replace('GATE_HASH', gate_hash)
    text = report.render(stage, "make mutation ARGS='laws'", {}, [], earlier)
    rows = {
        line.split('|')[1].strip(): line for line in text.splitlines() if line.startswith('| ')
    }
    assert rows['actuator_controller/laws.py'].startswith(
        f'| actuator_controller/laws.py | {laws_hash} | 2 | 2 |'
    )
    assert '100.0%' in rows['actuator_controller/laws.py']
    # gate was not reached by this run: the earlier figures, marked, and its survivor section
    assert rows['actuator_core/gate.py (earlier)'] == (
        f'| actuator_core/gate.py (earlier) | {gate_hash} | 3 | 2 | 0 | 1 | 0 | 0 | 66.7% | '
        '66.7% | 95% |'
    )
    assert rows['**all**'] == '| **all** | | 5 | 4 | 0 | 1 | 0 | 0 | 80.0% | | |'
    assert '## Surviving mutants (1)' in text and 'offer__mutmut_3' in text
    assert (
        "\n- Command: `make mutation ARGS='actuator_core.gate*'` Written 2026-12-01 22:07 UTC."
        in text
    )
    # without the earlier report, the unreached module is 'not checked'
    plain = report.render(stage, 'make mutation', {}, [])
    assert f'| actuator_core/gate.py | {gate_hash} | 3 | 0 | 0 | 0 | 0 | 3 |' in plain
    assert '(earlier)' not in plain
    # a third run keeps what the second kept from the first
    third = report.render(stage, 'make mutation', {}, [], text)
    assert f'| actuator_core/gate.py (earlier) | {gate_hash} | 3 | 2 | 0 | 1 |' in third
    # ... and lists both earlier runs flat, newest first, not quoted inside each other
    runs = [line for line in third.splitlines() if line.startswith('- Command:')]
    assert [r.split('`')[1] for r in runs] == [
        "make mutation ARGS='laws'",
        "make mutation ARGS='actuator_core.gate*'",
    ]
    assert not any(line.startswith('>') for line in third.splitlines())


def test_a_kept_row_whose_source_changed_since_its_run_is_stale_and_quotes_no_score(tmp_path):
    report = _report_module()
    stage = _stage(
        tmp_path,
        {
            'actuator_controller/laws.py': {'laws.x_a__mutmut_1': 1},
            'actuator_core/gate.py': {'actuator_core.gate.x__mutmut_1': None},
        },
    )
    text = report.render(stage, 'make mutation', {}, [], EARLIER.replace('GATE_HASH', 'abc'))
    rows = {
        line.split('|')[1].strip(): line for line in text.splitlines() if line.startswith('| ')
    }
    assert rows['actuator_core/gate.py (earlier)'] == (
        '| actuator_core/gate.py (earlier) | stale | 3 | 2 | 0 | 1 | 0 | 0 | — | — | 95% |'
    )
    assert rows['**all**'].endswith('| — | | |')  # no score over a stale row either


def test_every_row_of_the_report_matches_its_modules_source_or_withholds_its_score():
    """docs/mutation-report.md quotes no score of a module whose source changed since its run."""
    report = _report_module()
    text = (ROOT / 'docs' / 'mutation-report.md').read_text()
    rows = [line for line in text.splitlines() if line.startswith('| actuator_')]
    assert rows, 'no module rows in the report'
    stale = []
    for row in rows:
        cells = [c.strip() for c in row.strip('|').split('|')]
        module = cells[0].removesuffix(' (earlier)')
        if cells[1] == report.STALE:
            assert cells[8:10] == ['—', '—'], row  # a stale row quotes no score
            stale.append(module)
        else:
            assert cells[1] == report.source_hash(module), (
                f'{module} changed since its mutation run: rerun it '
                f'(make mutation ARGS="\'{module[:-3].replace("/", ".")}*\'") or mark it stale'
            )
    total = next(line for line in text.splitlines() if line.startswith('| **all**'))
    if stale:
        assert total.split('|')[9].strip() == '—', (stale, total)


def test_a_survivor_of_a_module_whose_name_starts_with_x_is_filed_under_it():
    """A survivor of actuator_core.xmath is filed under actuator_core/xmath.py."""
    report = _report_module()
    earlier = EARLIER.replace(
        'actuator_core.gate.xǁCommandGateǁoffer__mutmut_3', 'actuator_core.xmath.x_fsum__mutmut_1'
    )
    _, _, sections = report.earlier_report(earlier)
    assert list(sections) == ['actuator_core/xmath.py']
    _, _, sections = report.earlier_report(EARLIER)
    assert list(sections) == ['actuator_core/gate.py']


def test_unchecked_lists_the_unjudged_and_the_unexplained_survivors_of_the_globs(tmp_path):
    """No result, no test, or survived without an equivalent: listed; killed or explained: not."""
    spec = importlib.util.spec_from_file_location(
        'mutation_unchecked', ROOT / 'scripts' / 'mutation' / 'unchecked.py'
    )
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(ROOT / 'scripts' / 'mutation'))  # it imports report beside it
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(ROOT / 'scripts' / 'mutation'))
    stage = _stage(
        tmp_path,
        {
            'actuator_core/gate.py': {
                'actuator_core.gate.x_a__mutmut_1': None,
                'actuator_core.gate.x_a__mutmut_2': 0,
                'actuator_core.gate.x_a__mutmut_3': 0,
                'actuator_core.gate.x_a__mutmut_4': 1,
                'actuator_core.gate.x_a__mutmut_5': 33,  # no test covered it
            },
            'actuator_core/pairing.py': {'actuator_core.pairing.x_b__mutmut_1': None},
        },
    )
    explained = {'actuator_core.gate.x_a__mutmut_3': 'Equivalent: ...'}
    assert module.unchecked(stage, ['actuator_core.gate*'], explained) == [
        'actuator_core.gate.x_a__mutmut_1',
        'actuator_core.gate.x_a__mutmut_2',
        'actuator_core.gate.x_a__mutmut_5',
    ]
    assert len(module.unchecked(stage, [], explained)) == 4


def test_mark_stale_withholds_the_score_of_a_row_whose_module_changed_and_keeps_the_rest():
    report = _report_module()
    gate_hash = report.source_hash('actuator_core/gate.py')
    text = EARLIER.replace('GATE_HASH', gate_hash)  # laws: a hash that is not its code's
    marked = report.mark_stale(text)
    rows = {
        line.split('|')[1].strip(): line for line in marked.splitlines() if line.startswith('| ')
    }
    assert rows['actuator_controller/laws.py'] == (
        '| actuator_controller/laws.py | stale | 2 | 0 | 0 | 0 | 0 | 2 | — | — | 85% |'
    )
    assert rows['actuator_core/gate.py'].startswith(f'| actuator_core/gate.py | {gate_hash} |')
    assert rows['**all**'] == '| **all** |  | 5 | 2 | 0 | 1 | 0 | 2 | — |  |  |'
