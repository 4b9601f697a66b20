# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The joint contract: what the one joint node needs of a joint, simulated or real.

In the spirit of ros2_control's hardware components: a joint has a lifecycle and a cycle, and
never publishes topics itself. The joint node (``actuator_ros.joint_node``) owns the timing,
the command gate, stamp checks, the one-publisher guard, the brake policy, timeouts and
diagnostics; a joint only moves the hardware (or the model).

Lifecycle, each call may raise ``JointError`` with a one-line reason:
  configure   communication up and checked; nothing moves, the brake holds;
  activate    ready to apply torque; the brake holds until the first valid command;
  end_control the node ended control (a fault, a soft limit, a stale loop): 0 A and the brake
              now, whatever it takes (a synchronous drive needs cycles to take them); returns
              what the joint did, as the joint reports it;
  deactivate  0 A and the brake, calmly (a drive's quick-stop ramp included);
  cleanup     communication down;  close: at exit, from any state (both return warnings).
``describe`` says in one line what the joint shows after a stop; ``take_warnings`` hands the
node what the joint noticed without ending control (logged, counted in /diagnostics).
Cycle, once per sample k, called by the node in this order:
  write(current_a, brake)  what to apply from now on (the gate's decision for [t_k, t_k+1));
  read(t_k+1)              the sample at the next instant: angle, applied torque, health.
A simulated joint integrates [t_k, t_k+1) with what was written; a drive sends the target
with the SYNC at t_k+1 and answers with the angle latched at that SYNC (one sample of command
delay, as any synchronous drive). The first ``read`` after activate only samples.

Everything is SI (REP-103): rad, N m at the joint (output) shaft, A, integer ns stamps.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple, Optional

from actuator_core import limits
from actuator_core.loop_params import shared
from actuator_core.params import require_below, spec, validate


class JointError(RuntimeError):
    """A lifecycle step of a joint failed; the message is the one-line reason."""


class JointSample(NamedTuple):
    """What a joint reports at one sample instant."""

    stamp_ns: int  #: the sample instant t_k on the node's grid
    position_rad: float  #: joint angle (unwrapped, zero offset applied)
    effort_nm: float  #: torque applied at the joint shaft over the interval before t_k
    fault: str = ''  #: '' while the joint applies what it is told; else why not (control ends)


class Joint(ABC):
    """One joint behind the joint node: lifecycle, write, read, diagnostics."""

    #: Short name of the kind ('plant', 'cia402', ...), used in logs and diagnostics.
    kind: str = 'joint'
    #: True: a late cycle integrates every missed sample, one by one (a simulation must not
    #: lose time); False: missed cycles are skipped, as a real bus does (no replay).
    replays_missed: bool = False
    #: True: the joint can run in deterministic sim time (lockstep, /clock).
    supports_sim_time: bool = False

    def configure(self) -> list[str]:
        """Bring communication up and check it; return warnings (raise JointError)."""
        return []

    def activate(self) -> list[str]:
        """Make the joint ready to apply torque; the brake stays engaged (raise JointError)."""
        return []

    def end_control(self, reason: str) -> str:
        """Apply 0 A and the brake at once (control ended for ``reason``); say what was done."""
        self.write(0.0, True)
        return '0 A, brake engaged'

    def deactivate(self) -> list[str]:
        """Return to 0 A with the brake engaged, calmly; return warnings."""
        return []

    def cleanup(self) -> list[str]:
        """Bring communication down; return warnings."""
        return []

    def close(self) -> list[str]:
        """At exit, from any state: leave the joint safe, release every resource; warnings."""
        return self.cleanup()

    def describe(self) -> str:
        """One line on the joint's state as last read ('' when it has nothing to add)."""
        return ''

    def take_warnings(self) -> list[str]:
        """Return what the joint noticed since the last call without ending control."""
        return []

    @abstractmethod
    def write(self, current_a: float, brake: bool) -> None:
        """Apply ``current_a`` [A] (0 with ``brake``) from now until the next write."""

    @abstractmethod
    def read(self, stamp_ns: int) -> Optional[JointSample]:
        """Return the sample at ``stamp_ns``, or None when this cycle gave none (lost feedback)."""

    def diagnostics(self) -> dict[str, str]:
        """Key-values of the joint's own health, for /diagnostics."""
        return {}


@dataclass(frozen=True)
class JointSettings:
    """What every joint node has, whatever the joint: the loop's common settings (one source)."""

    sample_time_s: float = shared('sample_time_s')
    current_limit_a: float = shared('current_limit_a')
    command_timeout_s: float = spec(
        limits.COMMAND_TIMEOUT_S,
        'the joint applies 0 A when the newest command is older',
        's',
        *limits.TIMEOUT_RANGE_S,
    )
    brake_delay_s: float = spec(
        limits.BRAKE_DELAY_S,
        'after the command timeout, coast at 0 A this long before the holding brake engages',
        's',
        *limits.BRAKE_DELAY_RANGE_S,
    )
    joint_name: str = shared('joint_name')
    stop_after_s: float = spec(
        0.0,
        'end the run (exit 0) after this much sample time; 0 runs until stopped',
        's',
        0.0,
        1.0e6,
    )
    wait_for_subscribers: int = spec(
        0,
        'start sampling only once joint_states has this many subscribers (and '
        'current_command a publisher)',
        '',
        0,
        100,
    )
    lockstep_timeout_s: float = spec(
        2.0,
        'sim: wall time without the command for the newest sample after which control ends '
        '(a bounded run then exits 1 with that reason)',
        's',
        0.01,
        600.0,
    )
    position_min_rad: float = shared('position_min_rad')
    position_max_rad: float = shared('position_max_rad')
    velocity_max_rad_s: float = shared('velocity_max_rad_s')
    fresh_command_window_s: float = spec(
        limits.FRESH_COMMAND_WINDOW_S,
        'loop health: the window over which the share of fresh commands is judged',
        's',
        0.01,
        60.0,
    )
    fresh_command_share_min: float = spec(
        limits.FRESH_COMMAND_SHARE_MIN,
        'loop health: below this share of samples whose applied command answered one of the '
        'two newest samples, /diagnostics warns; 0 never',
        '',
        0.0,
        1.0,
    )
    stop_on_stale_loop: bool = spec(
        False,
        'loop health: end control (0 A, brake) when the share falls below '
        'fresh_command_share_min, instead of only warning',
    )

    def __post_init__(self) -> None:
        """Refuse out-of-range values and an empty soft-limit window."""
        validate(self)
        require_below(self, 'position_min_rad', 'position_max_rad')


class SoftLimits:
    """Position and velocity soft limits of the joint, checked on each sample it produces."""

    def __init__(self, settings: JointSettings, window_s: float = limits.SOFT_VELOCITY_WINDOW_S):
        """Limits from ``settings``; the speed is the angle's change over ``window_s`` [s]."""
        self.low, self.high = settings.position_min_rad, settings.position_max_rad
        self.velocity_max = settings.velocity_max_rad_s
        self.window_ns = int(round(window_s * 1e9))
        self._history: deque[tuple[int, float]] = deque()

    def reset(self) -> None:
        """Forget the previous samples (after a restart of sampling)."""
        self._history.clear()

    def check(self, stamp_ns: int, position_rad: float) -> str:
        """Return '' within the limits, else the reason (the node then brakes the joint).

        The speed: from the newest sample at least the window old (the oldest kept before
        that) to this one.
        """
        if not self.low <= position_rad <= self.high:
            self._history.append((stamp_ns, position_rad))
            return (
                f'joint angle {position_rad:.4f} rad outside the soft limits '
                f'[{self.low:g}, {self.high:g}] rad'
            )
        history = self._history
        while len(history) > 1 and history[1][0] <= stamp_ns - self.window_ns:
            history.popleft()
        base = history[0] if history else None
        history.append((stamp_ns, position_rad))
        if base is not None and stamp_ns > base[0]:
            speed = abs(position_rad - base[1]) / ((stamp_ns - base[0]) * 1e-9)
            if speed > self.velocity_max:
                span_ms = (stamp_ns - base[0]) / 1e6
                return (
                    f'joint speed {speed:.2f} rad/s over {span_ms:g} ms beyond the soft limit '
                    f'{self.velocity_max:g} rad/s'
                )
        return ''


class CommandFreshness:
    """Loop health seen by the joint: the share of recent samples driven by a fresh command.

    Fresh: the command applied over a sample interval answered one of the two newest samples
    (the window ``CommandBinding`` accepts); a held older command, 0 A after a timeout or no
    command is not. Counting starts at the first fresh command (before it the loop is not
    closed). Once ``window`` samples are counted the share is judged: below ``share_min`` the
    loop is degraded, and healthy again at ``share_min + FRESH_COMMAND_HYSTERESIS`` (capped at
    1). ``share_min`` 0 never degrades.
    """

    def __init__(self, window: int, share_min: float) -> None:
        """Judge the last ``window`` (>= 1) samples against ``share_min`` in [0, 1]."""
        if window < 1 or not 0.0 <= share_min <= 1.0:
            raise ValueError(f'window {window} must be >= 1 and share_min {share_min} in [0, 1]')
        self.window, self.share_min = window, share_min
        self.share_healthy = min(1.0, share_min + limits.FRESH_COMMAND_HYSTERESIS)
        self._recent: deque[bool] = deque(maxlen=window)
        self.reset()

    def reset(self) -> None:
        """Forget every sample (a new run)."""
        self._recent.clear()
        self.fresh = 0  # fresh samples in the window
        self.degraded = False
        self.episodes = 0  # times the loop became degraded

    @property
    def share(self) -> Optional[float]:
        """Share of fresh samples in the full window, None before it is full."""
        return self.fresh / self.window if len(self._recent) == self.window else None

    def add(self, fresh: bool) -> str:
        """Count one sample; return 'degraded' or 'healthy' when the verdict changes, else ''."""
        if not self._recent and not fresh:
            return ''
        if len(self._recent) == self.window:
            self.fresh -= self._recent[0]
        self._recent.append(bool(fresh))
        self.fresh += bool(fresh)
        share = self.share
        if share is None:
            return ''
        if not self.degraded and share < self.share_min:
            self.degraded = True
            self.episodes += 1
            return 'degraded'
        if self.degraded and share >= self.share_healthy:
            self.degraded = False
            return 'healthy'
        return ''

    def describe(self) -> str:
        """One line: the share over the window against the minimum."""
        share = self.share
        seen = 'not judged yet' if share is None else f'{share:.1%}'
        return (
            f'fresh commands {seen} of the last {self.window} samples (minimum '
            f'{self.share_min:.0%})'
        )
