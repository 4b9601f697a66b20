# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The controller node's parameters: declared with ranges and descriptions, checked, frozen."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from actuator_core import limits
from actuator_controller.excitation import ExcitationReference
from actuator_controller.laws import CONTROLLER_NAMES, GAINS_BY_NAME, CommonConfig
from actuator_controller.reference import REFERENCE_KINDS, SineReference, StepReference
from actuator_ros.parameters import (
    ParameterError,
    declare_choice,
    declare_number,
    declare_output_path,
    declare_spec_parameters,
    declare_text,
)
from actuator_ros.qos import MODES

#: What clocks the control update (README "Nodes and topic contract").
TRIGGERS = ('measurement', 'timer')


@dataclass(frozen=True)
class ControllerParameters:
    """What one configure of the controller node read (docs/parameters.md)."""

    mode: str  #: realtime or sim
    name: str  #: the control law (parameter 'controller')
    gains: Any  #: that law's gains (laws.GAINS_BY_NAME)
    common: CommonConfig  #: dt_s, current limit and the plant constants the laws share
    kind: str  #: the reference trajectory (parameter 'reference')
    amplitude: float  #: step/sine amplitude, rad
    frequency: float  #: sine angular frequency, rad/s
    measurement_timeout_ns: int  #: an older measurement: safe stop
    estimate_timeout_ns: int  #: an older estimate: safe stop
    following_error_limit_rad: float  #: |e| beyond latches a safe stop
    trigger: str  #: one of TRIGGERS
    future_tolerance_s: float  #: realtime: inputs stamped later than now plus this are refused
    joint_name: str  #: the joint's name in joint_states
    timing_log: str  #: per-update timing (.npz) path, '' for none
    state_rate_hz: float  #: rate of controller/state, 0: every sample
    excitation: ExcitationReference = ExcitationReference()  #: the excitation reference's shape


def declare_controller_parameters(node) -> ControllerParameters:
    """Declare (or read again at configure) and check every parameter of ``node``."""
    mode = declare_choice(
        node, 'mode', 'realtime', MODES, 'realtime: wall clock; sim: /clock lockstep'
    )
    name = declare_choice(node, 'controller', 'pp_nftsmc_eso', CONTROLLER_NAMES, 'control law')
    gains = declare_spec_parameters(node, GAINS_BY_NAME[name], prefix=f'{name}.')
    dt_s = declare_number(
        node,
        'sample_time_s',
        limits.SAMPLE_TIME_S,
        *limits.SAMPLE_TIME_RANGE_S,
        's',
        'sample period of the sensor and of the control law',
    )
    limit = declare_number(
        node,
        'current_limit_a',
        limits.CURRENT_LIMIT_A,
        *limits.CURRENT_LIMIT_RANGE_A,
        'A',
        'the commanded current is limited to +-this value',
    )
    common = declare_spec_parameters(
        node,
        CommonConfig,
        prefix='common.',
        exclude=('dt_s', 'current_limit_a'),
        dt_s=dt_s,
        current_limit_a=limit,
    )
    kind = declare_choice(node, 'reference', 'fast', REFERENCE_KINDS, 'reference trajectory')
    amplitude = declare_number(
        node,
        'reference_amplitude_rad',
        StepReference.amplitude_rad,
        -10.0,
        10.0,
        'rad',
        'step/sine amplitude',
    )
    frequency = declare_number(
        node,
        'reference_frequency_rad_s',
        SineReference.frequency_rad_s,
        0.0,
        1.0e3,
        'rad/s',
        'sine angular frequency',
    )
    excitation = declare_spec_parameters(node, ExcitationReference, prefix='excitation.')
    measurement_timeout_ns = int(
        1e9
        * declare_number(
            node,
            'measurement_timeout_s',
            limits.MEASUREMENT_TIMEOUT_S,
            *limits.TIMEOUT_RANGE_S,
            's',
            'older measurement: safe stop (0 A)',
        )
    )
    estimate_timeout_ns = int(
        1e9
        * declare_number(
            node,
            'estimate_timeout_s',
            limits.ESTIMATE_TIMEOUT_S,
            *limits.TIMEOUT_RANGE_S,
            's',
            'older estimate: safe stop (0 A)',
        )
    )
    following_error_limit_rad = declare_number(
        node,
        'following_error_limit_rad',
        limits.FOLLOWING_ERROR_LIMIT_RAD,
        1.0e-4,
        100.0,
        'rad',
        '|e| beyond latches a safe stop',
    )
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
    future_tolerance_s = declare_number(
        node,
        'future_stamp_tolerance_s',
        limits.FUTURE_STAMP_TOLERANCE_S,
        *limits.FUTURE_STAMP_TOLERANCE_RANGE_S,
        's',
        'realtime: inputs stamped later than now plus this are refused (clock offset '
        'between hosts)',
    )
    joint_name = declare_text(node, 'joint_name', 'joint', 'name of the joint in joint_states')
    timing_log = declare_output_path(
        node, 'timing_log', 'per-update timing (.npz) written at shutdown'
    )
    state_rate_hz = declare_number(
        node,
        'state_rate_hz',
        0.0,
        *limits.DIAGNOSTICS_RATE_RANGE_HZ,
        'Hz',
        'rate of controller/state on the sample stamps, and every change of status; 0: every '
        'sample, as the bag analysis needs',
    )
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
        amplitude=amplitude,
        frequency=frequency,
        measurement_timeout_ns=measurement_timeout_ns,
        estimate_timeout_ns=estimate_timeout_ns,
        following_error_limit_rad=following_error_limit_rad,
        trigger=trigger,
        future_tolerance_s=future_tolerance_s,
        joint_name=joint_name,
        timing_log=timing_log,
        state_rate_hz=state_rate_hz,
        excitation=excitation,
    )
