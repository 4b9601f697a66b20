# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``design_gains --joint FILE``: the identified joint as the design's nominal model and plant."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml

from actuator_core.identified import IdentifiedJoint, from_document, parameters_document
from actuator_plant.model import derive_constants
from actuator_studies.design import DesignRequest, run_design
from actuator_studies.evaluation import split_gains, worst_radius
from actuator_studies.identified_plant import joint_design, read_joint
from actuator_studies.space import BaseScenario, StudyInputError, build_scenario

JOINT = IdentifiedJoint(
    friction_model='drag',
    theta1=22.0,
    theta1_low=21.9,
    theta1_high=22.1,
    theta2=-9.0,
    theta2_low=-9.2,
    theta2_high=-8.8,
    coulomb_rad_s2=20.0,
    drag_per_rad=0.5,
)


def _file(tmp_path, joint=JOINT):
    path = tmp_path / 'joint.yaml'
    path.write_text(yaml.safe_dump(parameters_document(joint), sort_keys=False))
    return path


def test_the_design_plant_is_the_identified_joint(tmp_path):
    joint = read_joint(_file(tmp_path))
    assert joint == JOINT
    eso, settings, notes = joint_design(joint)
    base = BaseScenario(eso=eso, fixed=tuple(settings))
    scenario = build_scenario(base, {})
    plant = scenario.plant
    assert plant.nominal.theta1n == pytest.approx(22.0, rel=1e-12)  # the plant's theta1
    assert plant.nominal.theta2n == pytest.approx(-9.0, rel=1e-12)  # all viscous friction
    constants = derive_constants(plant)
    assert constants.stirring_coefficient_nm_s_rad == 0.0  # no stirring loss on top of theta2
    gear2 = plant.nominal.inertia_kg_m2 * plant.nominal.gear_ratio**2
    coulomb = (constants.seal_offset_nm + 1.0) / gear2  # eq. (42) at rest with c_v = 0
    assert coulomb == pytest.approx(20.0, rel=1e-9)
    for law in (scenario.common, scenario.eso):  # the law's and the observer's nominal model
        assert (law.theta1n, law.theta2n) == (22.0, -9.0)
    assert notes[-1] == 'the drag term has no counterpart in eq. (42): left out'


def test_the_margin_is_computed_with_the_identified_nominal_model(tmp_path):
    eso, settings, _ = joint_design(JOINT)
    values = {'pp_nftsmc_eso.k0_per_s': 100.0, 'eso.omega0_rad_s': 60.0}
    gains, kept = split_gains(values, eso)
    assert (kept.theta1n, kept.omega0_rad_s) == (22.0, 60.0)
    plant = build_scenario(BaseScenario(eso=eso, fixed=tuple(settings)), {}).plant
    plant = dataclasses.replace(plant, with_drift=False)
    identified = worst_radius(values, [plant], eso=eso)
    table1 = worst_radius(values, [plant])  # the same plant seen through Table 1's b0
    assert identified != table1


def test_a_file_without_the_identified_section_is_refused(tmp_path):
    path = tmp_path / 'gains.yaml'
    path.write_text(yaml.safe_dump({'actuator_eso': {'ros__parameters': {'theta1n': 30.0}}}))
    with pytest.raises(StudyInputError) as err:
        read_joint(path)
    assert str(err.value) == (
        f'--joint {path}: no identified_joint section (write one with bag_identify --params)'
    )


def test_design_gains_refuses_setting_what_the_joint_sets(tmp_path):
    req = DesignRequest(joint=str(_file(tmp_path)), settings=['nominal.inertia_kg_m2=1e-4'])
    with pytest.raises(StudyInputError) as err:
        run_design(req, tmp_path / 'out', log=lambda *_: None)
    assert str(err.value) == '--joint sets nominal.inertia_kg_m2: do not --set it too'


def test_the_identified_parameter_file_gives_both_nodes_the_model_and_reads_back_the_same():
    """The nominal model where the ESO and the controller read it; numbers as Python floats."""
    joint = IdentifiedJoint(theta1=np.float64(20.5), theta2=np.float64(-1.25))
    document = parameters_document(joint)
    nominal = {'theta1n': 20.5, 'theta2n': -1.25}
    assert document['actuator_eso'] == {'ros__parameters': nominal}
    assert document['actuator_controller'] == {'ros__parameters': {'common': nominal}}
    section = document['identified_joint']['ros__parameters']
    assert section['friction_model'] == 'coulomb_viscous'
    assert all(type(v) is float for k, v in section.items() if k != 'friction_model')
    assert from_document(document) == joint


def test_a_bad_identified_section_is_refused_with_what_is_wrong():
    """A friction model, an unknown name, a value that is not a number: each in one line."""
    with pytest.raises(ValueError) as refused:
        IdentifiedJoint(friction_model='lugre')
    assert str(refused.value) == (
        "friction_model must be one of coulomb_viscous, stribeck, drag: 'lugre'"
    )
    section = {'theta1': 20.0, 'theta3': 1.0, 'j': 2.0}
    with pytest.raises(ValueError) as refused:
        from_document({'identified_joint': {'ros__parameters': section}})
    assert str(refused.value) == 'identified_joint: unknown parameter(s) j, theta3'
    with pytest.raises(ValueError) as refused:
        from_document({'identified_joint': {'ros__parameters': {'theta1': 'fast'}}})
    assert str(refused.value) == (
        "IdentifiedJoint.theta1 = 'fast' is not a number: theta1 = k_t/(J N) (eq. (2))"
    )
    with pytest.raises(ValueError, match=r'^no identified_joint section \(write one with '):
        from_document({'actuator_eso': {}})
    with pytest.raises(ValueError, match=r'^identified_joint: .* must be a mapping, not list$'):
        from_document({'identified_joint': {'ros__parameters': ['theta1']}})
