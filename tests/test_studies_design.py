# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""design_gains.

The margin and current constraints hold for the designed set, the YAML is the nodes' format.
"""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from actuator_core import limits
from actuator_core.params import iter_specs
from actuator_controller.laws import PpNftsmcGains
from actuator_eso.observer import EsoGains
from actuator_studies.cli import design_main
from actuator_studies.design import DesignRequest, run_design
from actuator_studies.gains_yaml import read_gains_yaml, write_gains_yaml


pytestmark = pytest.mark.slow  # designs gains: seconds of simulation per test

ROOT = Path(__file__).resolve().parent.parent
CASE2 = ROOT / 'src' / 'actuator_bringup' / 'config' / 'case2_pp_nftsmc_eso.yaml'


def _keys(tree, prefix=''):
    """Dotted names of a nested dict."""
    out = set()
    for k, v in tree.items():
        out |= _keys(v, f'{prefix}{k}.') if isinstance(v, dict) else {prefix + k}
    return out


@pytest.fixture(scope='module')
def design(tmp_path_factory):
    """Return a small design: 8 trials over two corners, short runs."""
    out = tmp_path_factory.mktemp('design') / 'd'
    req = DesignRequest(
        trials=8,
        parallel=8,
        seed=0,
        corners=['depth_m=0,1000', 'condition.temperature_c=2'],
        duration_s=5.2,
    )
    return run_design(req, out, log=lambda *_: None), out


def test_paper_gains_fail_the_two_sample_margin_and_the_designed_ones_meet_every_constraint(
    design,
):
    report, out = design
    paper = report['trials'][0]
    assert (
        paper['pp_nftsmc_eso.k0_per_s'] == 100.0
        and paper['radius']['2'] > 1.0
        and not paper['feasible']
    )
    designed = report['comparison']['designed']
    assert max(designed['radius_by_delay'].values()) <= limits.DESIGN_TARGET_RADIUS
    assert designed['max_saturated_fraction'] <= limits.SATURATED_FRACTION_LIMIT
    feasible = [t for t in report['trials'] if t['feasible']]
    assert designed['percentile_error_rad'] == pytest.approx(
        min(t['objective_rad'] for t in feasible)
    )
    assert (
        json.loads((out / 'design.json').read_text())['target_radius']
        == limits.DESIGN_TARGET_RADIUS
    )


def test_gains_yaml_has_the_nesting_and_names_the_controller_and_eso_nodes_declare(design):
    report, out = design
    doc = yaml.safe_load(Path(report['gains_yaml']).read_text())
    case2 = yaml.safe_load(CASE2.read_text())
    ours = doc['actuator_controller']['ros__parameters']
    assert ours['controller'] == 'pp_nftsmc_eso'
    assert _keys(ours['pp_nftsmc_eso']) == _keys(
        case2['actuator_controller']['ros__parameters']['pp_nftsmc_eso']
    )
    assert _keys(ours['pp_nftsmc_eso']) == {n for n, _ in iter_specs(PpNftsmcGains)}
    assert _keys(doc['actuator_eso']['ros__parameters']) == _keys(
        case2['actuator_eso']['ros__parameters']
    )
    name, gains, eso = read_gains_yaml(Path(report['gains_yaml']))
    best = report['comparison']['designed']['gains']
    assert name == 'pp_nftsmc_eso' and gains.k0_per_s == best['pp_nftsmc_eso.k0_per_s']
    assert eso.omega0_rad_s == best['eso.omega0_rad_s']
    # the installed scenario file reads back as Table 4
    assert read_gains_yaml(CASE2)[1] == PpNftsmcGains() and read_gains_yaml(CASE2)[2] == EsoGains()


def test_a_gains_yaml_with_an_unknown_key_is_refused(tmp_path):
    path = write_gains_yaml(tmp_path / 'g.yaml', 'pp_nftsmc_eso', PpNftsmcGains(), EsoGains())
    doc = yaml.safe_load(path.read_text())
    doc['actuator_controller']['ros__parameters']['pp_nftsmc_eso']['k0'] = 5.0
    path.write_text(yaml.safe_dump(doc))
    from actuator_studies.space import StudyInputError

    with pytest.raises(StudyInputError, match='unknown parameter'):
        read_gains_yaml(path)


def test_a_designed_yaml_drives_a_sweep(design, tmp_path):
    from actuator_studies.sweep import SweepRequest, run_sweep

    report, _ = design
    summary = run_sweep(
        SweepRequest(vary=['depth_m=0,1000'], gains=report['gains_yaml'], duration_s=5.2),
        tmp_path / 's',
        progress=False,
    )
    worst = report['comparison']['designed']['worst_error_rad']
    assert np.isclose(summary['max_steady_error_rad']['max'], worst, rtol=1e-9)


@pytest.mark.parametrize(
    'args, expected',
    [
        (['--trials', '0'], 'must be >= 1'),
        (['--target-radius', '1.2'], 'target radius'),
        (['--corner', 'depth_m=0,20000'], 'valid range'),
        (['--corner', 'eso.omega0_rad_s=20,30'], 'is searched'),
        (['--ray', '127.0.0.1:9'], 'unreachable'),
    ],
)
def test_design_bad_input_is_one_line_exit_2(tmp_path, capsys, args, expected):
    assert design_main(args + ['--out', str(tmp_path / 'd')]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and expected in err
    assert not (tmp_path / 'd').exists()


def test_the_committed_designed_gains_keep_their_margin_at_two_samples_of_delay():
    from actuator_studies.design import Evaluator, corner_table, worst_radius
    from actuator_studies.space import BaseScenario

    name, gains, eso = read_gains_yaml(
        ROOT / 'src' / 'actuator_studies' / 'config' / 'pp_nftsmc_eso_designed.yaml'
    )
    plants = Evaluator(
        BaseScenario(), corner_table(['depth_m=0,2000', 'condition.temperature_c=-2,30'], name)
    ).plants
    designed = worst_radius(gains, eso, plants)
    paper = worst_radius(PpNftsmcGains(), EsoGains(), plants)
    assert name == 'pp_nftsmc_eso' and max(designed.values()) <= limits.DESIGN_TARGET_RADIUS
    assert paper[2] > 1.0 > paper[0]
