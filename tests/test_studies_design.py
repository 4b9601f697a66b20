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

from actuator_controller.laws import PpNftsmcGains
from actuator_core import limits
from actuator_core.params import iter_specs
from actuator_eso.observer import EsoGains
from actuator_studies.cli import design_main
from actuator_studies.design import DesignRequest, run_design
from actuator_studies.gains_yaml import read_gains_yaml, write_gains_yaml
from actuator_studies.space import StudyInputError

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
        validate_points=4,
        target_radius=0.999,  # stable at every drift vertex: most of 8 short trials qualify
    )
    return run_design(req, out, log=lambda *_: None), out


def test_paper_gains_fail_the_two_sample_margin_and_the_designed_ones_meet_every_constraint(
    design,
):
    report, out = design
    paper = report['trials'][0]
    assert (
        paper['pp_nftsmc_eso.k0_per_s'] == 100.0
        and paper['radius']['2'] > limits.DESIGN_TARGET_RADIUS  # a lower bound: stopped there
        and not paper['feasible']
    )
    designed = report['comparison']['designed']
    assert max(designed['radius_by_delay'].values()) <= report['target_radius'] == 0.999
    assert designed['max_saturated_fraction'] <= limits.SATURATED_FRACTION_LIMIT
    feasible = [t for t in report['trials'] if t['feasible']]
    assert designed['percentile_error_rad'] == pytest.approx(
        min(t['objective_rad'] for t in feasible)
    )
    assert json.loads((out / 'design.json').read_text())['target_radius'] == 0.999


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


def test_the_committed_designed_gains_keep_their_margin_at_the_drift_vertices():
    from actuator_studies.design import Evaluator, corner_table, gain_values
    from actuator_studies.evaluation import worst_radius
    from actuator_studies.space import BaseScenario

    name, gains, eso = read_gains_yaml(
        ROOT / 'src' / 'actuator_studies' / 'config' / 'pp_nftsmc_eso_designed.yaml'
    )
    evaluator = Evaluator(
        BaseScenario(), corner_table(['depth_m=0,2000', 'condition.temperature_c=-2,30'], name)
    )
    # 4 distinct plants (the delay does not change the plant), 4 drift vertices each
    assert len(evaluator.plants) == 4 and len(evaluator.margin_plants) == 16
    designed = worst_radius(gain_values(gains, eso), evaluator.margin_plants)
    paper = worst_radius(gain_values(PpNftsmcGains(), EsoGains()), evaluator.margin_plants)
    # the committed set was designed for 0.99 at the drift vertices (its header says so)
    assert name == 'pp_nftsmc_eso' and max(designed.values()) <= 0.99
    assert paper[2] > 1.0  # Table 4 fails at two samples of delay


def test_noisy_corners_get_several_seeds_from_the_design_seed_and_held_out_seeds_differ():
    from actuator_studies.design import Evaluator, corner_table
    from actuator_studies.evaluation import HELD_OUT_SEEDS_TAG
    from actuator_studies.space import BaseScenario

    corners = corner_table(['depth_m=0,1000', 'encoder.noise_std_rad=0,1e-4'], 'pp_nftsmc_eso')
    base = BaseScenario(fixed=(('encoder.counts_per_rev', 65536.0),))
    a = Evaluator(base, corners, seed=1, noise_seeds=3)
    assert a.n_cases == 2 + 2 * 3 and len(set(a.seeds.tolist())) == a.n_cases
    assert list(a.corner_of_case) == [0, 1, 1, 1, 2, 3, 3, 3]
    again, other = (
        Evaluator(base, corners, seed=1, noise_seeds=3),
        Evaluator(base, corners, seed=2, noise_seeds=3),
    )
    held = Evaluator(base, corners, seed=1, noise_seeds=3, tag=HELD_OUT_SEEDS_TAG)
    assert np.array_equal(a.seeds, again.seeds)
    assert not set(a.seeds.tolist()) & set(other.seeds.tolist())
    assert not set(a.seeds.tolist()) & set(held.seeds.tolist())


def test_the_report_holds_held_out_figures_beside_the_in_sample_ones(design):
    report, _ = design
    v = report['validation']
    assert v['held_out_seeds']['designed']['cases'] == 2  # no noise: one case per corner
    assert v['held_out_interior']['designed']['cases'] == 4
    interior = json.loads(json.dumps(report['request']))
    assert interior['validate_points'] == 4 and 'in_sample' in report
    assert report['provenance']['seeds']['design'] == 0


def test_a_design_in_a_journal_file_resumes_where_it_stopped(tmp_path):
    storage = str(tmp_path / 'journal.log')
    common = dict(
        parallel=2, corners=['depth_m=0'], duration_s=5.2, validate_points=0, storage=storage
    )
    first = run_design(DesignRequest(trials=2, **common), tmp_path / 'a', log=lambda *_: None)
    lines = []
    second = run_design(DesignRequest(trials=3, **common), tmp_path / 'b', log=lines.append)
    assert len(first['trials']) == 2 and len(second['trials']) == 3
    assert second['trials'][:2] == first['trials']  # the stored trials, not run again
    assert lines[0] == "design_gains: resuming 'design_gains' with 2 trials"
    with pytest.raises(StudyInputError, match='asked something else'):
        run_design(
            DesignRequest(trials=4, **{**common, 'corners': ['depth_m=1000']}), tmp_path / 'c'
        )


def test_exact_pruning_drops_only_trials_that_cannot_be_the_best():
    from actuator_studies.design import Evaluator, _simulate, corner_table, paper_values
    from actuator_studies.space import BaseScenario

    evaluator = Evaluator(
        BaseScenario(duration_s=5.2),
        corner_table(['depth_m=0,1000', 'condition.temperature_c=2,30'], 'pp_nftsmc_eso'),
    )
    paper = paper_values()
    (inc,) = evaluator.run([paper])
    incumbent = {
        'objective_rad': float(np.max(inc['error_rad'])),
        'case_errors_rad': inc['error_rad'].tolist(),
    }
    weak = {**paper, 'pp_nftsmc_eso.k1': 100.0, 'pp_nftsmc_eso.k2': 2.0}
    strong = {**paper, 'eso.omega0_rad_s': 80.0}
    candidates = [weak, strong]
    full = evaluator.run(candidates)
    req = DesignRequest(prune=True)
    outcome, pruned = _simulate(evaluator, candidates, [0, 1], incumbent, req)
    assert 0 in pruned  # the weak set is worse than Table 4 already on the hard quarter
    for i, o in enumerate(full):
        if i in pruned:  # exact: its worst case exceeds the incumbent's, it cannot be the best
            assert np.max(o['error_rad']) > incumbent['objective_rad']
            assert np.max(outcome[i]['error_rad']) <= np.max(o['error_rad']) * (1 + 1e-9)
            assert len(outcome[i]['error_rad']) == 1  # only the hard quarter of 4 cases ran
        else:  # a survivor gets every case, as without pruning
            assert np.allclose(outcome[i]['error_rad'], o['error_rad'], rtol=1e-9, atol=0)
    unpruned, none = _simulate(evaluator, candidates, [0, 1], incumbent, DesignRequest())
    assert not none and all(len(unpruned[i]['error_rad']) == 4 for i in (0, 1))
