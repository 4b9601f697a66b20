# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The core imports and runs with rclpy and launch made unimportable.

It is ROS-free by construction.
"""

import importlib
import pkgutil
import sys

import pytest

BLOCKED = ('rclpy', 'launch', 'launch_ros', 'rosidl_runtime_py', 'actuator_msgs', 'actuator_ros')
#: Every ROS-free package, and the ROS-free modules of the node packages.
ROS_FREE_PACKAGES = ('actuator_core', 'actuator_sim')
ROS_FREE_MODULES = (
    'actuator_plant.model',
    'actuator_plant.oil',
    'actuator_eso.observer',
    'actuator_controller.laws',
    'actuator_controller.ppf',
    'actuator_controller.reference',
    'actuator_controller.reference_sample',
    'actuator_controller.trajectory',
    'actuator_controller.trajectory_settings',
    'actuator_controller.goal_rules',
    'actuator_controller.goal_execution',
    'actuator_controller.commanded_reference',
    'actuator_controller.excitation',
    'actuator_analysis.identify',
    'actuator_analysis.identify_heldout',
    'actuator_analysis.identify_joint',
    'actuator_analysis.mismatch',
    'actuator_bench.host_stalls',
)


class _Refuse:
    """A meta-path finder that refuses the blocked top-level packages."""

    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in BLOCKED:
            raise ImportError(f'{name} is blocked by the ROS-free test')
        return None


@pytest.fixture
def without_ros(monkeypatch):
    """Fresh imports of the project's modules with the blocked packages unimportable."""
    saved = {
        name: mod
        for name, mod in sys.modules.items()
        if name.split('.')[0] in BLOCKED or name.startswith('actuator_')
    }
    for name in saved:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setattr(sys, 'meta_path', [_Refuse(), *sys.meta_path])
    yield
    for name in [n for n in sys.modules if n.startswith('actuator_')]:
        del sys.modules[name]


@pytest.mark.slow
def test_core_and_sim_import_and_run_without_rclpy_or_launch(without_ros):
    with pytest.raises(ImportError):
        importlib.import_module('rclpy')
    names = list(ROS_FREE_MODULES)
    for package in ROS_FREE_PACKAGES:
        pkg = importlib.import_module(package)
        names += [f'{package}.{m.name}' for m in pkgutil.iter_modules(pkg.__path__)]
    for name in names:
        importlib.import_module(name)
    assert len(names) > 15
    loop_module = importlib.import_module('actuator_sim.loop')
    scenarios = importlib.import_module('actuator_sim.scenarios')
    trace = loop_module.ClosedLoop(
        scenarios.paper_scenario('x', 'pp_nftsmc_eso', 'fast', 'deep_sea', 0.2)
    ).run()
    assert len(trace['t_s']) == 200 and abs(trace['error_rad']).max() < 0.1
