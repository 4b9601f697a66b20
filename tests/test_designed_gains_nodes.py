# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Nodes started with the designed gains (actuator_studies' parameter file) run with them.

The designed file is loaded after the scenario file (bringup --params-file), as
docs/how-to/change-gains.md#the-designed-gains-of-the-studies says; in deterministic sim time the
three processes then equal the offline core with the designed gains bit for bit, and differ from
the loop with Table 4's.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_share_directory

SCENARIO = 'case2_pp_nftsmc_eso'
DURATION_S = 1.0


def test_sim_loop_with_designed_gains_equals_the_offline_core_with_them(
    isolated: Path, capsys
) -> None:
    """The designed YAML by --params-file: 1000 of 1000 samples equal offline with those gains."""
    from actuator_analysis.analyze import load_run
    from actuator_bringup import runner as bringup
    from actuator_bringup.main import compare_with_offline
    from actuator_sim.loop import ClosedLoop
    from actuator_sim.params_yaml import all_scenarios
    from actuator_studies.gains_yaml import read_gains_yaml

    designed = (
        Path(get_package_share_directory('actuator_studies'))
        / 'config'
        / 'pp_nftsmc_eso_designed.yaml'
    )
    name, gains, eso = read_gains_yaml(designed)
    paper = all_scenarios()[SCENARIO]
    assert name == paper.controller and gains != paper.gains and eso != paper.eso
    args = ['--scenario', SCENARIO, '--mode', 'sim', '--duration', str(DURATION_S)]
    assert bringup.main([*args, '--params-file', str(designed)]) == 0
    out = capsys.readouterr().out
    report = json.loads(out[out.index('{') :])
    assert all(code == 0 for code in report['exit_codes'].values()), report
    run = load_run(Path(report['bag']), quiet=True)
    with_designed = ClosedLoop(
        dataclasses.replace(paper, gains=gains, eso=eso, duration_s=DURATION_S)
    ).run()
    same = compare_with_offline(run, with_designed)
    assert same['samples_compared'] == 1000 and same['identical'], same
    with_table4 = ClosedLoop(dataclasses.replace(paper, duration_s=DURATION_S)).run()
    assert not compare_with_offline(run, with_table4)['identical']
    with pytest.raises(SystemExit):  # a missing file: one line from argparse, exit 2
        bringup.main([*args, '--params-file', str(isolated / 'missing.yaml')])
    assert '--params-file' in capsys.readouterr().err
