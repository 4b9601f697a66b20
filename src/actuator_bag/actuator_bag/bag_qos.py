# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The offered-QoS record of a rosbag2 v9 topic.

It is the ``offered_qos_profiles`` YAML of metadata and MCAP channels.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import yaml

from .errors import BagWriteError

#: The rmw value of an infinite duration, as the graph reports it for default deadline etc.
#: (sec, nsec).
DURATION_INFINITE = (9223372036, 854775807)

_HISTORY = ('system_default', 'keep_last', 'keep_all', 'unknown')
_RELIABILITY = ('system_default', 'reliable', 'best_effort', 'unknown', 'best_available')
_DURABILITY = ('system_default', 'transient_local', 'volatile', 'unknown', 'best_available')
_LIVELINESS = ('system_default', 'automatic', 'manual_by_topic', 'unknown', 'best_available')


def _check_choice(name: str, value: str, choices: Sequence[str]) -> None:
    """Raise BagWriteError unless value is one of choices."""
    if value not in choices:
        raise BagWriteError(f'QoS {name} must be one of {", ".join(choices)}, not {value!r}')


def _time_dict(value: tuple[int, int]) -> dict[str, int]:
    """Convert a (sec, nsec) pair to rosbag2's YAML map."""
    return {'sec': int(value[0]), 'nsec': int(value[1])}


@dataclass(frozen=True)
class QosProfile:
    """One offered QoS profile as rosbag2 v9 stores it; durations are (sec, nsec)."""

    history: str = 'keep_last'
    depth: int = 10
    reliability: str = 'reliable'
    durability: str = 'volatile'
    deadline: tuple[int, int] = DURATION_INFINITE
    lifespan: tuple[int, int] = DURATION_INFINITE
    liveliness: str = 'automatic'
    liveliness_lease_duration: tuple[int, int] = DURATION_INFINITE
    avoid_ros_namespace_conventions: bool = False

    def __post_init__(self) -> None:
        """Validate the policy names and the depth."""
        _check_choice('history', self.history, _HISTORY)
        _check_choice('reliability', self.reliability, _RELIABILITY)
        _check_choice('durability', self.durability, _DURABILITY)
        _check_choice('liveliness', self.liveliness, _LIVELINESS)
        if self.depth < 0:
            raise BagWriteError(f'QoS depth must be >= 0, not {self.depth}')

    def as_dict(self) -> dict[str, Any]:
        """Return the v9 YAML map of this profile."""
        return {
            'history': self.history,
            'depth': int(self.depth),
            'reliability': self.reliability,
            'durability': self.durability,
            'deadline': _time_dict(self.deadline),
            'lifespan': _time_dict(self.lifespan),
            'liveliness': self.liveliness,
            'liveliness_lease_duration': _time_dict(self.liveliness_lease_duration),
            'avoid_ros_namespace_conventions': bool(self.avoid_ros_namespace_conventions),
        }

    @classmethod
    def from_dict(cls, dct: Mapping[str, Any]) -> QosProfile:
        """Profile from a v9 YAML map."""

        def pair(key: str) -> tuple[int, int]:
            return (int(dct[key]['sec']), int(dct[key]['nsec']))

        return cls(
            history=str(dct['history']),
            depth=int(dct['depth']),
            reliability=str(dct['reliability']),
            durability=str(dct['durability']),
            deadline=pair('deadline'),
            lifespan=pair('lifespan'),
            liveliness=str(dct['liveliness']),
            liveliness_lease_duration=pair('liveliness_lease_duration'),
            avoid_ros_namespace_conventions=bool(dct['avoid_ros_namespace_conventions']),
        )


def qos_to_yaml(profiles: Sequence[QosProfile]) -> str:
    """Format the offered_qos_profiles string of an MCAP channel (a YAML list of v9 maps)."""
    return yaml.safe_dump(
        [p.as_dict() for p in profiles], default_flow_style=False, sort_keys=False
    )


def qos_from_yaml(text: str) -> tuple[QosProfile, ...]:
    """Profiles from an offered_qos_profiles string (empty string: none)."""
    loaded = yaml.safe_load(text) if text.strip() else []
    if not isinstance(loaded, list):
        raise BagWriteError('offered_qos_profiles is not a YAML list')
    return tuple(QosProfile.from_dict(x) for x in loaded)
