# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Golden figures of the offline paper cases: compute, compare with tests/golden/, update.

The offline core is deterministic, so every figure ``offline_sim case1|case2`` prints (max
steady-state error, RMS error, max |u|, saturated share, spectral radius) is pinned to the
digits it prints, and each case's float trace to one SHA-256 checksum (any bit that moves shows).
``tests/test_golden_offline.py`` runs the comparison; a change made on purpose is written back
with the command in ``REGENERATE``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from actuator_sim.loop import ClosedLoop
from actuator_sim.offline import _fmt, run_scenario
from actuator_sim.scenarios import case1, case2

GOLDEN_PATH = Path(__file__).resolve().parent / 'golden' / 'offline.json'
REGENERATE = 'python tests/golden_offline.py --update  (after `source scripts/env.sh`)'
CASES = {'case1': case1, 'case2': case2}
#: Seconds of each run behind the quick checksum.
SHORT_S = 1.0


def printed_figures(metrics, radius: float) -> dict[str, str]:
    """Return the figures of one run as offline_sim's table prints them (same formats)."""
    return {
        'max_steady_error_rad': _fmt(metrics.max_steady_error_rad),
        'rms_error_rad': _fmt(metrics.rms_error_rad),
        'max_abs_current_a': f'{metrics.max_abs_current_a:.2f}',
        'saturated_percent': f'{100 * metrics.saturated_fraction:.1f}',
        'bounds_kept': str(metrics.bounds_kept),
        'spectral_radius': f'{radius:.4f}',
    }


def trace_checksum(traces: dict[str, dict[str, np.ndarray]]) -> str:
    """SHA-256 of every run's trace: run names and fields sorted, values as float64 bytes."""
    digest = hashlib.sha256()
    for run in sorted(traces):
        for field in sorted(traces[run]):
            values = np.ascontiguousarray(traces[run][field], dtype='<f8')
            digest.update(f'{run}/{field}/{values.size};'.encode())
            digest.update(values.tobytes())
    return digest.hexdigest()


def compute_case(case: str) -> dict:
    """Run one paper case: {'runs': {name: printed figures}, 'trace_sha256': checksum}.

    Also the checksum of the first ``SHORT_S`` of every run ('short_trace_sha256'), which the
    quick unit set compares (a second of each run instead of ten).
    """
    runs, traces = {}, {}
    for scenario, _paper in CASES[case]():
        trace, metrics, radius, _wall = run_scenario(scenario)
        runs[scenario.name] = printed_figures(metrics, radius)
        traces[scenario.name] = trace
    return {
        'runs': runs,
        'trace_sha256': trace_checksum(traces),
        'short_trace_sha256': short_checksum(case),
    }


def short_checksum(case: str) -> str:
    """SHA-256 of the first SHORT_S of every run of a case (the same scenarios, shorter)."""
    return trace_checksum(
        {scenario.name: ClosedLoop(scenario).run() for scenario, _ in CASES[case](SHORT_S)}
    )


def load_golden(path: Path = GOLDEN_PATH) -> dict:
    """Return the stored golden figures, {case: {'runs': ..., 'trace_sha256': ...}}."""
    return json.loads(path.read_text())


def differences(old: dict, new: dict) -> list[tuple[str, str, str]]:
    """Return (what, stored, now) for each figure of one case that differs (none: all equal)."""
    rows = []
    for run in sorted(set(old['runs']) | set(new['runs'])):
        before, after = old['runs'].get(run, {}), new['runs'].get(run, {})
        for name in sorted(set(before) | set(after)):
            if before.get(name) != after.get(name):
                rows.append(
                    (f'{run}.{name}', before.get(name, '(none)'), after.get(name, '(none)'))
                )
    for key in ('trace_sha256', 'short_trace_sha256'):
        if key in new and old.get(key) != new[key]:
            rows.append((key, old.get(key, '(none)')[:16], new[key][:16]))
    return rows


def report(case: str, rows: list[tuple[str, str, str]]) -> str:
    """Put old and new side by side, with the command that writes the new figures on purpose."""
    width = max(len(r[0]) for r in rows)
    lines = [
        f'{case}: {len(rows)} golden figure(s) changed',
        f'{"figure":<{width}}  stored -> now',
    ]
    lines += [f'{what:<{width}}  {old} -> {new}' for what, old, new in rows]
    lines.append(f'if the change is intended, regenerate: {REGENERATE}')
    return '\n'.join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Compare the current figures with the stored ones (exit 1 on a difference), or --update."""
    parser = argparse.ArgumentParser(prog='golden_offline', description=__doc__.splitlines()[0])
    parser.add_argument('--update', action='store_true', help=f'write {GOLDEN_PATH.name} anew')
    parser.add_argument(
        '--case', action='append', choices=tuple(CASES), help='one case (repeatable; default all)'
    )
    args = parser.parse_args(argv)
    cases = args.case or list(CASES)
    stored = load_golden() if GOLDEN_PATH.exists() else {}
    changed = False
    for case in cases:
        now = compute_case(case)
        rows = differences(stored[case], now) if case in stored else [('(new case)', '-', '-')]
        if rows:
            changed = True
            print(report(case, rows))
        else:
            print(f'{case}: every golden figure unchanged')
        stored[case] = now
    if args.update:
        GOLDEN_PATH.parent.mkdir(parents=True, exist_ok=True)
        GOLDEN_PATH.write_text(json.dumps(stored, indent=2, sort_keys=True) + '\n')
        print(f'written: {GOLDEN_PATH}')
        return 0
    return 1 if changed else 0


if __name__ == '__main__':
    sys.exit(main())
