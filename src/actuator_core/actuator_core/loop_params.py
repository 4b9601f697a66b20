# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The parameters the nodes of one joint's loop share, each specified once.

The joint (plant or driver), the observer and the controller all read the sample time, the current
limit, the joint's name and the mode; the observer and the controller the nominal model, the
future-stamp tolerance and the lockstep's start-up hold; the joint and the controller the soft
limits (the joint brakes at them, the controller refuses goals that come near them). Each node's
specification takes these fields from here (``shared``), so a name has one description, one unit
and one range wherever it is declared (tests/test_param_docs.py holds the generated reference to
that).
"""

from __future__ import annotations

from typing import Any

from actuator_core import limits
from actuator_core.params import spec

#: The loop's modes: wall-clock real time, or a lockstep on the joint's /clock.
MODES = ('realtime', 'sim')

_SHARED: dict[str, dict[str, Any]] = {
    'mode': dict(
        default='realtime',
        description='realtime: wall-clock 1 kHz, best-effort streams; sim: lockstep on the '
        "joint's /clock, reliable streams",
        choices=MODES,
    ),
    'sample_time_s': dict(
        default=limits.SAMPLE_TIME_S,
        description="sample period of the loop: the joint's (a drive's SYNC period), the "
        "observer's and the law's",
        unit='s',
        low=limits.SAMPLE_TIME_RANGE_S[0],
        high=limits.SAMPLE_TIME_RANGE_S[1],
    ),
    'current_limit_a': dict(
        default=limits.CURRENT_LIMIT_A,
        description="the loop's current limit: the law commands within +-this, the observer "
        'and the joint refuse a command beyond it',
        unit='A',
        low=limits.CURRENT_LIMIT_RANGE_A[0],
        high=limits.CURRENT_LIMIT_RANGE_A[1],
        low_open=True,
    ),
    'joint_name': dict(default='joint', description='name of the joint in joint_states'),
    'future_stamp_tolerance_s': dict(
        default=limits.FUTURE_STAMP_TOLERANCE_S,
        description='realtime: inputs stamped later than now plus this are refused (the clock '
        'offset between hosts)',
        unit='s',
        low=limits.FUTURE_STAMP_TOLERANCE_RANGE_S[0],
        high=limits.FUTURE_STAMP_TOLERANCE_RANGE_S[1],
    ),
    'theta1n': dict(
        default=limits.THETA1N,
        description="theta_1n = k_tn/(J_n N), eq. (3): the nominal model's current-to-"
        "acceleration gain (the observer's b0)",
        unit='rad/s^2/A',
        low=0.0,
        high=1.0e6,
        low_open=True,
    ),
    'position_min_rad': dict(
        default=-limits.POSITION_LIMIT_RAD,
        description='soft limit: below this angle the joint brakes, and goals whose x1d comes '
        f'within {limits.GOAL_POSITION_MARGIN_RAD:g} rad of it are refused (set both nodes in '
        'one /** section)',
        unit='rad',
        low=-limits.POSITION_LIMIT_RAD,
        high=limits.POSITION_LIMIT_RAD,
    ),
    'position_max_rad': dict(
        default=limits.POSITION_LIMIT_RAD,
        description='soft limit: above this angle the joint brakes, and goals whose x1d comes '
        f'within {limits.GOAL_POSITION_MARGIN_RAD:g} rad of it are refused (set both nodes in '
        'one /** section)',
        unit='rad',
        low=-limits.POSITION_LIMIT_RAD,
        high=limits.POSITION_LIMIT_RAD,
    ),
    'velocity_max_rad_s': dict(
        default=limits.VELOCITY_LIMIT_RAD_S,
        description='soft speed limit: beyond it (over the last 20 ms of samples) the joint '
        f"brakes, and goals whose |x1d'| exceeds {limits.GOAL_VELOCITY_SHARE:g} of it are "
        'refused (set both nodes in one /** section)',
        unit='rad/s',
        low=0.0,
        high=limits.VELOCITY_LIMIT_RAD_S,
        low_open=True,
    ),
    'lockstep_subscribers': dict(
        default=1,
        description="sim: this node's output (eso/estimate, current_command) is held until its "
        'topic has this many subscribers, then sent in order: a sample sent before the next '
        "node's reader matched is lost, and the lockstep stops at start-up",
        low=0,
        high=100,
    ),
    'theta2n': dict(
        default=limits.THETA2N,
        description="theta_2n = -k_bn/J_n, eq. (3): the nominal model's viscous term",
        unit='1/s',
        low=-1.0e4,
        high=1.0e4,
    ),
}


def shared(name: str) -> Any:
    """Return a dataclass field for shared parameter ``name`` (one definition for every node)."""
    return spec(**_SHARED[name])
