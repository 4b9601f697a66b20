# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What the controller node says: its recovery lines, its /diagnostics, its timing summary.

``ControllerReport`` is a part of ``ControllerNode`` (a mixin): it reads the node's counters,
its assembly and its timing log, and changes nothing the control path reads.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from actuator_core.assembly import AT_LIMIT_SAMPLES, ControlSample
from actuator_core.health import HealthMonitor, Level, Snapshot
from actuator_core.stats import percentiles
from actuator_core.status import Status

if TYPE_CHECKING:
    from rclpy.impl.rcutils_logger import RcutilsLogger

    from actuator_controller.controller_parameters import ControllerParameters
    from actuator_core.assembly import ControlSampleAssembly
    from actuator_core.binding import MeasurementPlausibility
    from actuator_core.sample_log import SampleLog
    from actuator_ros.log import RateLimitedLog


class ControllerReport:
    """Logs, /diagnostics and the timing summary of the controller node."""

    # What ControllerNode (and ManagedNode) hold and this part reads or counts.
    params: ControllerParameters
    active: bool
    log: RateLimitedLog
    assembly: ControlSampleAssembly
    plausibility: MeasurementPlausibility
    timing: SampleLog
    status: Status
    conflict: str
    resyncs: int
    gap_resyncs: int
    reported_rows: int
    measurements_in: int
    estimates_in: int
    late: int
    refused: int
    stale_events: int
    envelope_restarts: int
    refusals: dict[str, int]

    if TYPE_CHECKING:  # rclpy's Node

        def get_logger(self) -> RcutilsLogger: ...

        def get_name(self) -> str: ...

    def _log_recovery(self, sample: ControlSample) -> None:
        """Say when a resync starts, when RECOVERING starts and when it ends."""
        a = self.assembly
        started = a.resyncs != self.resyncs  # one line per resync episode the assembly began
        self.resyncs = a.resyncs
        if a.gap_resyncs != self.gap_resyncs:
            self.gap_resyncs = a.gap_resyncs
            self.get_logger().warning(
                f'no law sample for more than {a.gap_limit_ns / 1e6:g} ms, or an input that old '
                '(the joint was braked): '
                'resync, 0 A and brake while the observer converges, then the reference restarts '
                "from the joint's angle"
            )
        elif started:
            self.get_logger().warning(
                'the observer restarted or the time base jumped: resync, 0 A and brake while '
                "the observer converges, then the reference restarts from the joint's angle"
            )
        if sample.status is Status.RECOVERING and self.status is not Status.RECOVERING:
            if a.at_limit_run > AT_LIMIT_SAMPLES:
                self.log.warn(
                    'at_limit',
                    lambda: (
                        f'RECOVERING: the command sat at the current limit for more than '
                        f'{AT_LIMIT_SAMPLES} samples; the state says RECOVERING until it leaves it'
                    ),
                )
            else:
                self.log.warn(  # rate-limited: a marginal envelope may flip it often
                    'recovering',
                    lambda: (
                        'RECOVERING: the law runs again after a gap or a resync (or |e| left the '
                        'envelope); the state says RECOVERING until it is back inside'
                    ),
                )
        elif sample.status is Status.OK and self.status is Status.RECOVERING:
            self.log.info('recovered', lambda: 'recovered: status OK again')

    # --- /diagnostics ----------------------------------------------------------------------------
    def health_monitor(self) -> HealthMonitor:
        """Rules of /diagnostics: STALE when an input stops; WARN on refusals, lateness, resync."""
        self.reported_rows = 0
        return HealthMonitor(
            self.get_name(),
            inputs={'measurements_in': 'joint_states', 'estimates_in': 'eso/estimate'},
            warn_on={
                'refused *': 'refused inputs',
                'late': 'late samples',
                'missed': 'missed samples',
                'stale_events': 'stale-input safe stops',
                'resyncs': 'resyncs',
                'envelope_restarts': 'envelope restarts',
            },
        )

    def health(self) -> Snapshot:
        """Report to /diagnostics: counts, status, timing percentiles since the last report."""
        a, rows = self.assembly, self.timing.since(self.reported_rows)
        self.reported_rows += len(rows)
        values: dict[str, object] = {
            'controller': self.params.name,
            'mode': self.params.mode,
            'status': self.status.name,
        }
        values.update(percentiles(rows[:, 3] / 1e3, 'compute_us'))
        if self.params.mode == 'realtime':
            values.update(percentiles(rows[:, 2] / 1e3, 'latency_us'))
        problems = [(Level.ERROR, f'{self.conflict}: commanding 0 A')] if self.conflict else []
        if a.latched:
            problems.append((Level.ERROR, 'safe stop latched (0 A) until cleanup'))
        elif self.active and self.status is not Status.OK:
            problems.append((Level.WARN, f'status {self.status.name}: 0 A'))
        counts = {
            'updates': self.timing.rows,
            'measurements_in': self.measurements_in,
            'estimates_in': self.estimates_in,
            'late': self.late,
            'missed': a.missed,
            'refused_inputs': self.refused,
            'stale_events': self.stale_events,
            'resyncs': a.resyncs,
            'envelope_restarts': self.envelope_restarts,
            **{f'refused {k}': n for k, n in self.refusals.items()},
        }
        return Snapshot('active' if self.active else 'inactive', counts, values, problems)

    # --- shutdown --------------------------------------------------------------------------------
    def timing_summary(self) -> dict[str, int | float | None]:
        """Period, latency and compute-time percentiles of the control updates so far."""
        rows = self.timing.array()
        a = self.assembly
        summary: dict[str, int | float | None] = {
            'updates': self.timing.rows,
            'measurements_in': self.measurements_in,
            'estimates_in': self.estimates_in,
            'late': self.late,
            'missed': a.missed,
            'unanswered': a.unanswered,
            'stale_events': self.stale_events,
            'refused_inputs': self.refused,
            'corrected_estimates': a.corrected,
            'envelope_restarts': self.envelope_restarts,
            'resyncs': a.resyncs,
            'gap_resyncs': a.gap_resyncs,
            'refused_estimates_binding': a.refused,
            'estimate_conflicts': a.conflicts,
            'implausible_measurements': self.plausibility.refused,
        }
        if len(rows) > 2:
            summary.update(percentiles((rows[1:, 0] - rows[:-1, 0]) / 1e3, 'period_us', mean=True))
            summary.update(percentiles(rows[:, 3] / 1e3, 'compute_us'))
            if self.params.mode == 'realtime':
                summary.update(percentiles(rows[:, 2] / 1e3, 'latency_us'))
        return summary

    def close_log(self) -> None:
        """Log the timing summary; write the raw timing samples if asked."""
        summary = self.timing_summary()
        self.get_logger().info(
            'timing '
            + ' '.join(
                f'{k}={v:.1f}' if isinstance(v, float) else f'{k}={v}' for k, v in summary.items()
            )
        )
        if self.params.timing_log:
            self.timing.save(self.params.timing_log)
