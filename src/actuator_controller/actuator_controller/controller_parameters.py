# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The controller node's parameters, declared from specifications, checked, frozen.

Numbers and names are dataclass fields with their unit, range and description
(``ControllerSettings``; the law's gains, ``CommonConfig`` and the trajectory settings of
``trajectory_settings`` likewise), declared with ``declare_spec_parameters``; choices among
names are ``declare_choice``. docs/reference/parameters.md is generated from these declarations.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from actuator_controller.excitation import ExcitationReference
from actuator_controller.laws import CONTROLLER_NAMES, GAINS_BY_NAME, CommonConfig
from actuator_controller.reference import REFERENCE_KINDS, SineReference, StepReference
from actuator_controller.trajectory_settings import (
    GoalSettings,
    JointConstraints,
    TrajectoryConstraints,
    TrajectorySettings,
)
from actuator_core import limits
from actuator_core.loop_params import shared
from actuator_core.params import spec, validate
from actuator_ros.parameters import (
    TIMING_LOG_DESCRIPTION,
    ParameterError,
    declare_choice,
    declare_output_path,
    declare_shared,
    declare_spec_parameters,
)

#: What clocks the control update (docs/concepts/architecture.md#what-clocks-the-controller).
TRIGGERS = ('measurement', 'timer')


@dataclass(frozen=True)
class ControllerSettings:
    """The controller node's own numbers and names (besides the law's gains)."""

    sample_time_s: float = shared('sample_time_s')
    current_limit_a: float = shared('current_limit_a')
    reference_amplitude_rad: float = spec(
        StepReference.amplitude_rad, 'step/sine amplitude', 'rad', -10.0, 10.0
    )
    reference_frequency_rad_s: float = spec(
        SineReference.frequency_rad_s, 'sine angular frequency', 'rad/s', 0.0, 1.0e3
    )
    measurement_timeout_s: float = spec(
        limits.MEASUREMENT_TIMEOUT_S,
        'older measurement: safe stop (0 A)',
        's',
        *limits.TIMEOUT_RANGE_S,
    )
    estimate_timeout_s: float = spec(
        limits.ESTIMATE_TIMEOUT_S, 'older estimate: safe stop (0 A)', 's', *limits.TIMEOUT_RANGE_S
    )
    following_error_limit_rad: float = spec(
        limits.FOLLOWING_ERROR_LIMIT_RAD, '|e| beyond latches a safe stop', 'rad', 1.0e-4, 100.0
    )
    future_stamp_tolerance_s: float = shared('future_stamp_tolerance_s')
    joint_name: str = shared('joint_name')
    lockstep_subscribers: int = shared('lockstep_subscribers')
    state_rate_hz: float = spec(
        0.0,
        'rate of controller/state on the sample stamps, and every change of status; 0: every '
        'sample, as the bag analysis needs',
        'Hz',
        *limits.DIAGNOSTICS_RATE_RANGE_HZ,
    )

    def __post_init__(self) -> None:
        """Refuse out-of-range values."""
        validate(self)

    @property
    def measurement_timeout_ns(self) -> int:
        """An older measurement: safe stop [ns]."""
        return int(1e9 * self.measurement_timeout_s)

    @property
    def estimate_timeout_ns(self) -> int:
        """An older estimate: safe stop [ns]."""
        return int(1e9 * self.estimate_timeout_s)


@dataclass(frozen=True)
class ControllerParameters:
    """What one configure of the controller node read (docs/reference/parameters.md)."""

    mode: str  #: realtime or sim
    name: str  #: the control law (parameter 'controller')
    gains: Any  #: that law's gains (laws.GAINS_BY_NAME)
    common: CommonConfig  #: dt_s, current limit and the plant constants the laws share
    kind: str  #: the reference (parameter 'reference'): hold, or a built-in trajectory
    trigger: str  #: one of TRIGGERS
    timing_log: str  #: per-update timing (.npz) path, '' for none
    settings: ControllerSettings  #: the node's own numbers
    trajectory: TrajectorySettings  #: what goals are judged by (reference hold)
    excitation: ExcitationReference  #: the excitation reference's shape (reference excitation)


def declare_trajectory_parameters(node, joint_names) -> TrajectorySettings:
    """Declare JTC's goal parameters: the global ones and ``constraints.<joint>.*`` per joint."""
    return TrajectorySettings(
        joint_names=tuple(joint_names),
        goal=declare_spec_parameters(node, GoalSettings),
        constraints=declare_spec_parameters(node, TrajectoryConstraints, prefix='constraints.'),
        joints=tuple(
            declare_spec_parameters(node, JointConstraints, prefix=f'constraints.{joint}.')
            for joint in joint_names
        ),
    )


def declare_controller_parameters(node) -> ControllerParameters:
    """Declare (or read again at configure) and check every parameter of ``node``."""
    mode = declare_shared(node, 'mode')
    name = declare_choice(node, 'controller', 'pp_nftsmc_eso', CONTROLLER_NAMES, 'control law')
    gains = declare_spec_parameters(node, GAINS_BY_NAME[name], prefix=f'{name}.')
    settings = declare_spec_parameters(node, ControllerSettings)
    common = declare_spec_parameters(
        node,
        CommonConfig,
        prefix='common.',
        exclude=('dt_s', 'current_limit_a'),
        dt_s=settings.sample_time_s,
        current_limit_a=settings.current_limit_a,
    )
    kind = declare_choice(
        node,
        'reference',
        'hold',
        REFERENCE_KINDS,
        "hold: hold the joint's angle until a goal (follow_joint_trajectory, joint_trajectory) "
        "moves it; else a built-in trajectory from activation (the paper's slow and fast, a "
        "step, a sine, an identification run's excitation), which takes no goals",
    )
    excitation = declare_spec_parameters(node, ExcitationReference, prefix='excitation.')
    trigger = declare_choice(
        node,
        'trigger',
        'measurement',
        TRIGGERS,
        'measurement: control each sample as soon as its measurement and estimate are in; '
        'timer: control on a timer of sample_time_s with the newest measurement (a drive '
        "whose cycle differs from the loop's); realtime only",
    )
    if trigger == 'timer' and mode == 'sim':
        raise ParameterError(
            "parameter 'trigger' = 'timer' refused in sim mode: the lockstep advances "
            'only when a command answers its sample'
        )
    timing_log = declare_output_path(node, 'timing_log', TIMING_LOG_DESCRIPTION)
    trajectory = declare_trajectory_parameters(node, (settings.joint_name,))
    node.refuse_sim_time_in_realtime(mode)
    if mode == 'sim' and not node.get_parameter('use_sim_time').value:
        raise ParameterError(
            "parameter 'use_sim_time' must be true in sim mode (the plant owns /clock)"
        )
    return ControllerParameters(
        mode=mode,
        name=name,
        gains=gains,
        common=common,
        kind=kind,
        trigger=trigger,
        timing_log=timing_log,
        settings=settings,
        trajectory=trajectory,
        excitation=excitation,
    )
