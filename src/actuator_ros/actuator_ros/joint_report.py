# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What the joint node says: its closing line, host stalls, the joint's warnings, /diagnostics.

``JointReport`` is a part of ``JointNode`` (a mixin): it reads the node's counters, its gate
and its joint, and changes nothing the sampling loop reads.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Optional

from actuator_core.health import HealthMonitor, Level, Snapshot

if TYPE_CHECKING:
    from rclpy.impl.rcutils_logger import RcutilsLogger

    from actuator_core.gate import CommandGate, Held
    from actuator_core.joint import CommandFreshness, Joint
    from actuator_core.sample_log import SampleLog
    from actuator_ros.log import RateLimitedLog


class JointReport:
    """The closing line, the host-stall and joint-warning lines and /diagnostics of the node."""

    # What JointNode (and ManagedNode) hold and this part reads or counts.
    summary: str
    mode: str
    active: bool
    log: RateLimitedLog
    timing_log: str
    samples_log: SampleLog
    joint: Optional[Joint]
    gate: CommandGate
    held: Held
    freshness: CommandFreshness
    period_ns: int
    sample_index: int
    refused: int
    lockstep_timeouts: int
    skipped_cycles: int
    longest_stall_cycles: int
    lost_feedback: int
    joint_warnings: int
    stopped_reason: str
    conflict: bool

    if TYPE_CHECKING:  # rclpy's Node

        def get_logger(self) -> RcutilsLogger: ...

        def get_name(self) -> str: ...

    @property
    def _joint(self) -> Joint:
        """The joint of the configured node (``build`` makes it, ``drop`` closes it)."""
        assert self.joint is not None, 'the node is not configured'
        return self.joint

    def close_log(self) -> None:
        """Log a one-line summary; write the per-sample log if asked."""
        if self.timing_log:
            self.samples_log.save(self.timing_log)
        self.get_logger().info(
            f'stopped at sample {self.sample_index}; refused commands {self.gate.refused} by '
            f'value and {self.refused} by stamp, command timeouts {self.gate.timeouts}, '
            f'lockstep timeouts {self.lockstep_timeouts}; cycles skipped by host stalls '
            f'{self.skipped_cycles} (the longest stall {self.longest_stall_cycles}), '
            f'cycles without feedback {self.lost_feedback}'
        )

    def _host_stalled(self, skipped: int) -> None:
        """Count and log the cycles a host stall took (a real joint skips them)."""
        self.skipped_cycles += skipped
        self.longest_stall_cycles = max(self.longest_stall_cycles, skipped)
        self.log.warn(
            'host_stall',
            lambda: (
                f'host stall: {skipped} cycles skipped (the sampling thread woke '
                f'{skipped * self.period_ns * 1e-6:.0f} ms late; {self.skipped_cycles} in all, '
                f'the longest {self.longest_stall_cycles})'
            ),
        )

    def _log_warnings(self) -> None:
        """Log and count what the joint noticed without ending control (EMCY warnings)."""
        if self.joint is None:
            return
        for text in self.joint.take_warnings():
            self.joint_warnings += 1
            self.get_logger().warning(f'{self.summary}: {text}')

    def health_monitor(self) -> HealthMonitor:
        """Rules of /diagnostics: STALE without samples; WARN on refusals and timeouts."""
        return HealthMonitor(
            self.get_name(),
            inputs={'samples': 'samples from the joint'},
            warn_on={
                'refused_by_stamp': 'commands refused by stamp',
                'refused_by_value': 'commands refused by value',
                'command_timeouts': 'command timeouts (0 A, then the brake)',
                'lockstep_timeouts': 'sim lockstep timeouts (control ended)',
                'joint_warnings': 'warnings of the joint (logged)',
            },
            hardware_id=self._joint.kind,
        )

    def health(self) -> Snapshot:
        """Report to /diagnostics: counts, the joint's own key-values, why control ended."""
        problems = []
        if self.stopped_reason:
            problems.append((Level.ERROR, f'control ended: {self.stopped_reason}'))
        if self.conflict:
            problems.append((Level.ERROR, 'more than one publisher on current_command'))
        if self.freshness.degraded and not self.stopped_reason:
            problems.append((Level.WARN, f'loop too slow: {self.freshness.describe()}'))
        share = self.freshness.share
        return Snapshot(
            'active' if self.active else 'inactive',
            {
                'samples': self.sample_index + 1,
                'refused_by_stamp': self.refused,
                'refused_by_value': self.gate.refused,
                'command_timeouts': self.gate.timeouts,
                'lockstep_timeouts': self.lockstep_timeouts,
                'joint_warnings': self.joint_warnings,
            },
            {
                **self._joint.diagnostics(),  # the node's own keys below win (its 'brake': held)
                'mode': self.mode,
                'brake': bool(self.held.brake),
                'held': self.held.reason or f'{self.held.current_a:.3f} A',
                'fresh commands [%]': 'not judged yet' if share is None else f'{100 * share:.1f}',
            },
            problems,
        )
