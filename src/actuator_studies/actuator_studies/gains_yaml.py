# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Gain sets as ROS 2 parameter files the controller and ESO nodes load as they are.

Same nesting as the installed scenario files (``actuator_bringup/config/*.yaml``):
``actuator_controller: ros__parameters: {controller: NAME, NAME: {gains, ppf: {...}}}`` and
``actuator_eso: ros__parameters: {omega0_rad_s, l1, l2, l3, theta1n, theta2n}``; every key is
a parameter the node declares from the same spec'd dataclasses. Reading refuses a key no
node declares, so a typo never falls back silently to Table 4's value.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import yaml

from actuator_controller.laws import GAINS_BY_NAME
from actuator_core.params import build, iter_specs
from actuator_eso.observer import EsoGains
from actuator_sim.params_yaml import dotted
from actuator_studies.space import StudyInputError


def parameters_document(controller: str, gains, eso: EsoGains) -> dict:
    """Return the two nodes' parameters.

    For ``gains`` of ``controller`` and the observer ``eso``.
    """
    return {
        'actuator_eso': {'ros__parameters': dataclasses.asdict(eso)},
        'actuator_controller': {
            'ros__parameters': {'controller': controller, controller: dataclasses.asdict(gains)}
        },
    }


def write_gains_yaml(path: Path, controller: str, gains, eso: EsoGains, header: str = '') -> Path:
    """Write the parameter file (a ``# ...`` header first when given)."""
    text = yaml.safe_dump(parameters_document(controller, gains, eso), sort_keys=False)
    comment = ''.join(f'# {line}\n' for line in header.splitlines())
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(comment + text)
    return path


def _build_checked(cls: type, values: dict, where: str):
    """``cls`` from dotted values, refusing names it does not declare."""
    known = {name for name, _ in iter_specs(cls)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise StudyInputError(f'{where}: unknown parameter(s) {", ".join(unknown)}')
    try:
        return build(cls, values)
    except (TypeError, ValueError) as exc:
        raise StudyInputError(f'{where}: {exc}') from None


def read_gains_yaml(path: Path) -> tuple[str, object, EsoGains]:
    """Read (controller, gains, ESO gains) of a parameter file.

    One written by ``write_gains_yaml``, or the scenario files.
    """
    try:
        doc = yaml.safe_load(Path(path).read_text())
        ctrl = doc['actuator_controller']['ros__parameters']
        name = ctrl['controller']
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise StudyInputError(f'{path}: not a controller parameter file ({exc})') from None
    if name not in GAINS_BY_NAME:
        raise StudyInputError(f'{path}: unknown controller {name!r}')
    gains = _build_checked(GAINS_BY_NAME[name], dotted(ctrl.get(name, {})), f'{path}: {name}')
    eso_params = (doc.get('actuator_eso') or {}).get('ros__parameters') or {}
    eso = _build_checked(EsoGains, dotted(eso_params), f'{path}: actuator_eso')
    return name, gains, eso
