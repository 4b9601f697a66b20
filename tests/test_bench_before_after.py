# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""scripts/bench_before_after.py: the side-by-side table of two versions' benchmark runs."""

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _module():
    spec = importlib.util.spec_from_file_location(
        'bench_before_after', ROOT / 'scripts' / 'bench_before_after.py'
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _summary(folder: Path, cpu_plant: float, speed: float) -> None:
    """One benchmark's summary.json, as actuator_bench.bench writes it, in ``folder``/<stamp>/."""
    out = folder / '20261204T000000Z'
    out.mkdir(parents=True)
    runs = [
        {'variant': 'sim', 'figures': {'speed_x': speed, 'cpu_plant_pct': 99.0}},
        {'variant': 'realtime_fifo50', 'figures': {'cpu_plant_pct': cpu_plant, 'speed_x': 7.0}},
        {'variant': 'realtime_normal', 'figures': {'cpu_plant_pct': 1000.0}},  # not compared
    ]
    (out / 'summary.json').write_text(json.dumps({'runs': runs}))


def test_the_table_gives_each_versions_median_range_and_ratio(tmp_path, capsys):
    for r, (before, after) in enumerate([(30.0, 33.0), (28.0, 31.0), (29.0, 36.0)], start=1):
        _summary(tmp_path / f'round{r}_before', before, 1.0 + r / 10)
        _summary(tmp_path / f'round{r}_after', after, 2.0)
    assert _module().main(['--table', str(tmp_path)]) == 0
    lines = {line[:40].strip(): line[40:].split() for line in capsys.readouterr().out.splitlines()}
    # median (range) of the three rounds, the other variants' figures left out; after / before
    assert lines['CPU plant (joint) [% of a core]'] == ['29', '(28-30)', '33', '(31-36)', '1.14']
    assert lines['lockstep speed [x real time]'] == ['1.2', '(1.1-1.3)', '2', '(2-2)', '1.67']
    assert lines['CPU plant (joint), lockstep [%]'] == ['99', '(99-99)', '99', '(99-99)', '1.00']
    assert lines['CPU ESO [%]'] == ['-', '-', '-']  # in no run: no figure, no ratio
