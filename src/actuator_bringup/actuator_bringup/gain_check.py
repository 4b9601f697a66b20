# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Before a run starts: the named gains judged stable or not at the joint's own delay.

A synchronous drive applies each command one SYNC later than the paper's loop; Table 4's gains
are marginal there (linearised radius 1.003 at a vertex of the drift (41)) and chattered at the
current limit through the simulated drive. The runner and the launch file build the gains the
nodes will run (the scenario's file, then the user's parameter files, as rcl applies them) and
judge the linearised sampled loop (actuator_sim.stability) with the joint's delay at every
vertex of the scenario's drift; a set at radius 1 or more is refused with the radius in the
line, unless the user insists (``allow_unstable_gains``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from actuator_bringup.run_options import node_section
from actuator_controller.laws import GAINS_BY_NAME
from actuator_core.params import build
from actuator_eso.observer import EsoGains
from actuator_plant.model import PLANT_NODE_NAME, plant_from_values
from actuator_sim.params_yaml import all_scenarios
from actuator_sim.scenarios import DRIVE_DELAY_SAMPLES
from actuator_sim.stability import drift_extremes, radius_along_envelope

#: Samples each joint adds between a command and its application (a synchronous drive: one).
JOINT_DELAY_SAMPLES = {
    'plant': 0,
    'cia402_sim': DRIVE_DELAY_SAMPLES,
    'cia402': DRIVE_DELAY_SAMPLES,
}
#: At or above this linearised spectral radius a gain set is unstable there.
UNSTABLE_RADIUS = 1.0


class UnstableGains(ValueError):
    """The gains are unstable at the joint's delay; the message says so in one line."""


def loop_radius(scenario: str, files: Sequence[Path], joint: str) -> tuple[str, float]:
    """Return (controller, the worst linearised radius over the drift's vertices and time).

    ``files``: the scenario's parameter file first, then the user's. The joint: the simulated
    one as the files give it to the plant node; a drive's, the scenario's when it is one of
    actuator_sim's, else the paper's. A drifting joint is judged at each vertex of its drift.
    """
    controller_values = node_section(files, 'actuator_controller')
    name = controller_values.get('controller', 'pp_nftsmc_eso')
    prefix = f'{name}.'
    gains = build(
        GAINS_BY_NAME[name],
        {k[len(prefix) :]: v for k, v in controller_values.items() if k.startswith(prefix)},
    )
    eso = build(EsoGains, node_section(files, 'actuator_eso')) if name != 'pi' else None
    if joint == 'plant':  # the simulated joint the run's files describe
        plant = plant_from_values(node_section(files, PLANT_NODE_NAME))
    else:  # a drive's joint: the scenario's, or the paper's
        known = all_scenarios().get(scenario)
        plant = (known or all_scenarios()['case2_pp_nftsmc_eso']).plant
    delay = JOINT_DELAY_SAMPLES.get(joint, 0)
    worst = max(
        radius
        for vertex in (drift_extremes(plant) if plant.with_drift else [plant])
        for _, radius in radius_along_envelope(
            name, gains, eso=eso, plant_delay=delay, plant=vertex
        )
    )
    return name, worst


def check_gains(
    scenario: str, files: Sequence[Path], joint: str, allow_unstable: bool
) -> tuple[float, str]:
    """Return (radius, a warning or ''); refuse an unstable set unless ``allow_unstable``."""
    name, radius = loop_radius(scenario, files, joint)
    if radius < UNSTABLE_RADIUS:
        return radius, ''
    delay = JOINT_DELAY_SAMPLES.get(joint, 0)
    what = (
        f'the {name} gains of {scenario} are unstable with joint {joint} ({delay} sample(s) of '
        f'command delay): linearised radius {radius:.3f} >= {UNSTABLE_RADIUS:g} at a vertex of '
        'the drift'
    )
    if not allow_unstable:
        raise UnstableGains(
            f'{what}; name gains stable there, or insist with allow_unstable_gains'
        )
    return radius, f'{what}: run anyway (allow_unstable_gains)'
