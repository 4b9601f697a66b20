# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The benchmark's variants (``bench``): the ways of running the nodes, and which to run.

A variant is one mode (real or sim time), its scheduling (SCHED_FIFO priority, CPU pinning), how
the nodes are started (runner or ros2 launch, separate processes or composed), the diagnostic
topics' rate, Fast DDS's publication mode and whether the recorder runs; its slug names its
folders and CSV rows, its title its section of the table.
"""

from __future__ import annotations

import dataclasses
import shutil
from dataclasses import dataclass
from typing import Optional, Sequence

from actuator_ros import realtime

RT_VARIANTS = (
    'normal',
    'fifo',
    'pinned',
    'fifo-pinned',
    'fifo-launch',
    'normal-composed',
    'fifo-composed',
    'pinned-composed',
    'fifo-pinned-composed',
)
#: Fast DDS publication modes a run can be given (RMW_FASTRTPS_PUBLICATION_MODE): those the
#: runner chooses between (actuator_ros.realtime.PUBLICATION_MODES).
PUBLICATION_MODES = tuple(sorted(set(realtime.PUBLICATION_MODES.values()), reverse=True))
#: Fast DDS transports a run can be given: the runner's own (UDP only in real time,
#: actuator_ros.middleware), or Fast DDS's default with shared memory, which the runner keeps.
TRANSPORTS = ('udp', 'shared-memory')
#: ROS modes: real time; sim time across processes; sim time with the three nodes in one
#: process; the same with that process recording the bag itself (composition.compose).
MODES = ('realtime', 'sim', 'sim-composed', 'sim-composed-in-process')


@dataclass(frozen=True)
class Variant:
    """One way of running the nodes: mode, SCHED_FIFO priority (0 = normal) and CPU pinning."""

    mode: str
    rt_priority: int = 0
    pinned: bool = False
    launched: bool = False  # started by ros2 launch instead of the runner
    composed: bool = False  # joint, ESO and controller in one process (composition.compose)
    diagnostics_rate_hz: Optional[float] = None  # controller/state, plant/truth (None: default)
    publication_mode: str = ''  # RMW_FASTRTPS_PUBLICATION_MODE ('': the runner's)
    transport: str = ''  # one of TRANSPORTS ('': the runner's, not named)
    recorded: bool = True  # the recorder runs (its bag gives the tracking figures)
    in_process: bool = False  # a composed loop records its bag itself (no recorder process)

    @property
    def slug(self) -> str:
        """Short name for folders and the CSV."""
        sched = f'fifo{self.rt_priority}' if self.rt_priority else 'normal'
        composed = '_composed' if self.composed else ''
        base = (
            f'sim{composed}'
            if self.mode == 'sim'
            else f'realtime_{sched}{"_pinned" if self.pinned else ""}'
            f'{"_launch" if self.launched else ""}{composed}'
        )
        if self.diagnostics_rate_hz is not None:
            base += f'_diag{self.diagnostics_rate_hz:g}hz'
        if self.publication_mode:
            base += f'_{self.publication_mode.lower()}'
        if self.transport:
            base += f'_{self.transport.replace("-", "_")}'
        if self.in_process:
            base += '_in_process'
        return base if self.recorded else f'{base}_unrecorded'

    @property
    def title(self) -> str:
        """Heading in the table."""
        one = ', joint + ESO + controller in one process' if self.composed else ''
        if self.diagnostics_rate_hz is not None:
            rate = self.diagnostics_rate_hz
            one += f', controller/state and plant/truth at {f"{rate:g} Hz" if rate else "1 kHz"}'
        if self.publication_mode:
            one += f', Fast DDS {self.publication_mode.lower()} publication'
        if self.transport:
            one += f', Fast DDS over {"UDP" if self.transport == "udp" else "shared memory"}'
        if not self.recorded:
            one += ', no recorder'
        if self.in_process:
            one += ', recorded in-process (no recorder process)'
        if self.mode == 'sim':
            return f'sim: deterministic sim time (lockstep), normal scheduling{one}'
        sched = (
            f'SCHED_FIFO {self.rt_priority}'
            if self.rt_priority
            else 'normal scheduling (SCHED_OTHER)'
        )
        pinned = (
            ', pinned (the process on CPU 0)'
            if self.composed
            else ', pinned (plant CPU 0; ESO, controller CPU 1)'
        )
        return (
            f'realtime: {sched}'
            f'{pinned if self.pinned else ""}'
            f'{", started by ros2 launch" if self.launched else ""}{one}'
        )


def missing_tool(variant: Variant) -> Optional[str]:
    """Say what a variant needs that this machine lacks, or None."""
    if variant.launched and shutil.which('ros2') is None:
        return 'ros2 launch is not installed (no ros2 on PATH)'
    return None


def make_variants(
    modes: Sequence[str],
    rt_variants: Sequence[str],
    rt_priority: int,
    diagnostics_rates: Sequence[float] = (),
    publication_modes: Sequence[str] = (),
    without_recorder: bool = False,
    transports: Sequence[str] = (),
) -> list[Variant]:
    """Return the variants to run, sim first, in the order given.

    Each real-time variant runs once more per rate of ``diagnostics_rates``; every variant runs
    once per mode of ``publication_modes`` (none: the runner's own mode); every real-time
    variant once per transport of ``transports`` (none: the runner's; sim time keeps its own,
    shared memory); and each once more without the recorder if ``without_recorder``.
    """
    variants = [Variant('sim')] if 'sim' in modes else []
    if 'sim-composed' in modes:
        variants.append(Variant('sim', composed=True))
    if 'sim-composed-in-process' in modes:
        variants.append(Variant('sim', composed=True, in_process=True))
    if 'realtime' in modes:
        for name in dict.fromkeys(rt_variants):
            variant = Variant(
                'realtime',
                rt_priority if 'fifo' in name else 0,
                'pinned' in name,
                'launch' in name,
                'composed' in name,
            )
            variants.append(variant)
            variants += [
                dataclasses.replace(variant, diagnostics_rate_hz=float(rate))
                for rate in dict.fromkeys(diagnostics_rates)
            ]
    if publication_modes:
        variants = [
            dataclasses.replace(v, publication_mode=mode)
            for v in variants
            for mode in dict.fromkeys(publication_modes)
        ]
    if transports:  # real time only: the runner keeps shared memory in sim time
        variants = [
            dataclasses.replace(v, transport=transport)
            for v in variants
            for transport in (dict.fromkeys(transports) if v.mode == 'realtime' else ('',))
        ]
    if without_recorder:  # an in-process recording unrecorded is the composed loop unrecorded
        variants = [
            v
            for r in variants
            for v in (r, dataclasses.replace(r, recorded=False, in_process=False))
        ]
    return list(dict.fromkeys(variants))
