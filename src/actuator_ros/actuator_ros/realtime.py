# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Real-time settings as node parameters, applied before rclpy.init.

They are ros2_control's thread_priority and cpu_affinity. SCHED_FIFO must be set before
``rclpy.init``: the middleware's threads (Fast DDS receive and event threads), which every message
passes through, inherit the policy only if it is set before they exist (measured:
plant-to-controller delivery p99 9.3 ms -> 0.17 ms). A node cannot read its parameters before init,
so ``pre_init_settings`` reads them all from the same sources rcl will (``-p name:=value`` and
``--params-file`` sections for this node or ``/**``), and the node declares them again afterwards
so that ``ros2 param`` shows them. ``nice`` is the process's niceness under normal scheduling
(``setpriority``): a process outside the loop (the recorder) is started at
``actuator_bringup.run_description.RECORDER_NICE``, so that the kernel's fair scheduler gives the
loop's processes a contended core first; below 0 needs CAP_SYS_NICE, as SCHED_FIFO does. Memory is
not locked (ros2_control's lock_memory): mlockall made 300-400 MB resident per node.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, fields
from typing import Any, Optional, Sequence

import yaml

EXECUTORS = ('events', 'single_threaded')
#: The range of ``nice`` (Linux setpriority).
NICE_RANGE = (-20, 19)


#: The variable rmw_fastrtps reads its publication mode from when rclpy.init creates it.
PUBLICATION_MODE_VARIABLE = 'RMW_FASTRTPS_PUBLICATION_MODE'
#: Fast DDS's publication mode for a process run_node starts, unless the environment sets it,
#: by how its threads are scheduled. ASYNCHRONOUS (a sending thread per writer) only where that
#: thread runs at once, under SCHED_FIFO; SYNCHRONOUS (a publish sends in the caller's thread)
#: under normal scheduling and in sim time. Measured in two benchmark invocations of 2026-12-05
#: (2 x 20 s per variant, real time over UDP; docs/performance.md): under normal scheduling
#: every hand-off to a sending thread is a chance to wait a time slice, asynchronous lost
#: 1596-1853 samples of 20000 against 132-147 synchronous (composed 842-1067 against 141-222);
#: under SCHED_FIFO, composed, asynchronous keeps the latency p50 at 264 us against 362 us
#: (rcl_publish holds the GIL while it sends, so a synchronous send delays the next callback of
#: the process). Over shared memory a synchronous publish waited on a subscriber that did not
#: read; over UDP (actuator_ros.middleware) it does not: 5000 publishes of controller/state at
#: 1 kHz to a stopped (SIGSTOP) subscriber, synchronous mean 30 us, worst 461 us; asynchronous
#: 42 us, 4.9 ms. A lockstep saves the sending thread's wake-up on every hop.
PUBLICATION_MODES = {'sim': 'SYNCHRONOUS', 'fifo': 'ASYNCHRONOUS', 'normal': 'SYNCHRONOUS'}


def publication_mode(sim: bool, fifo: bool) -> str:
    """Return Fast DDS's publication mode for a process (PUBLICATION_MODES)."""
    return PUBLICATION_MODES['sim' if sim else 'fifo' if fifo else 'normal']


@dataclass(frozen=True)
class RealtimeSettings:
    """thread_priority (SCHED_FIFO 1-99, 0: normal), cpu_affinity ('' = any), executor, nice."""

    thread_priority: int = 0
    cpu_affinity: str = ''
    executor: str = 'events'
    nice: int = 0

    def problems(self) -> list[str]:
        """Return what is invalid, one line each."""
        out = []
        if not isinstance(self.thread_priority, int) or not 0 <= self.thread_priority <= 99:
            out.append(
                f"parameter 'thread_priority' = {self.thread_priority!r} refused: "
                'an integer in [0, 99]'
            )
        low, high = NICE_RANGE
        if not isinstance(self.nice, int) or not low <= self.nice <= high:
            out.append(f"parameter 'nice' = {self.nice!r} refused: an integer in [{low}, {high}]")
        if self.executor not in EXECUTORS:
            out.append(
                f"parameter 'executor' = {self.executor!r} refused: one of {', '.join(EXECUTORS)}"
            )
        try:
            self.cpus()
        except ValueError:
            out.append(
                f"parameter 'cpu_affinity' = {self.cpu_affinity!r} refused: "
                'a comma-separated CPU list such as "1" or "0,1"'
            )
        return out

    def cpus(self) -> set[int]:
        """Return the CPU set, empty for no pinning."""
        text = str(self.cpu_affinity).strip()
        return {int(c) for c in text.split(',')} if text else set()

    def apply(self) -> Optional[str]:
        """Pin and raise the process (all threads created later inherit).

        Return the refusal, if any.
        """
        notes = []
        if self.cpus():
            try:
                os.sched_setaffinity(0, self.cpus())
            except OSError as exc:
                notes.append(
                    f'cpu_affinity {self.cpu_affinity!r} refused by the kernel ({exc}); not pinned'
                )
        if self.nice:
            try:
                os.setpriority(os.PRIO_PROCESS, 0, self.nice)
            except OSError as exc:
                kept = os.getpriority(os.PRIO_PROCESS, 0)
                notes.append(
                    f'nice {self.nice} refused by the kernel ({exc}); running at nice {kept}'
                )
        if self.thread_priority:
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.thread_priority))
            except OSError as exc:
                notes.append(
                    f'SCHED_FIFO priority {self.thread_priority} refused by the kernel ({exc}); '
                    'running with normal scheduling '
                    '(grant CAP_SYS_NICE or an rtprio limit to enable it)'
                )
        return '; '.join(notes) or None


def _value(text: str):
    """Return a ``-p`` value as rcl parses it (YAML scalar)."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def pre_init_settings(args: Sequence[str], node_name: str) -> RealtimeSettings:
    """Return the real-time parameters for ``node_name`` from ROS arguments, before rclpy exists.

    Later wins.
    """
    found = _parameters(args, node_name, tuple(f.name for f in fields(RealtimeSettings)))
    # as the command line gives them: RealtimeSettings.problems judges them
    values: dict[str, Any] = {k: (str(v) if k == 'cpu_affinity' else v) for k, v in found.items()}
    return RealtimeSettings(**values)


def in_sim_time(args: Sequence[str], node_name: str) -> bool:
    """Whether ``node_name``'s ROS arguments say ``mode`` sim or ``use_sim_time`` true."""
    found = _parameters(args, node_name, ('mode', 'use_sim_time'))
    return found.get('mode') == 'sim' or found.get('use_sim_time') is True


def _parameters(args: Sequence[str], node_name: str, names: Sequence[str]) -> dict:
    """Return the values of ``names`` for ``node_name`` in ROS arguments (later wins)."""
    found: dict = {}
    in_ros, it = False, iter(list(args))
    for arg in it:
        if arg == '--ros-args':
            in_ros = True
        elif arg == '--':
            in_ros = False
        elif in_ros and arg in ('-p', '--param'):
            name, _, text = next(it, '').partition(':=')
            node, _, name = name.rpartition(':')  # 'node:name' applies to that node only
            if name in names and node in ('', node_name, f'/{node_name}', '/**', '**'):
                found[name] = _value(text)
        elif in_ros and arg == '--params-file':
            found.update(_from_file(next(it, ''), node_name, names))
    return found


def _from_file(path: str, node_name: str, names: Sequence[str]) -> dict:
    """Entries of ``names`` in the sections of a parameter file that apply to ``node_name``."""
    try:
        with open(path) as f:
            data = yaml.safe_load(f) or {}
    except (OSError, yaml.YAMLError):
        return {}  # rcl reports an unreadable file itself, with its own message
    out: dict = {}
    for key in ('/**', node_name, f'/{node_name}'):
        section = data.get(key, {}) if isinstance(data, dict) else {}
        params = section.get('ros__parameters', {}) if isinstance(section, dict) else {}
        out.update({k: v for k, v in params.items() if k in names})
    return out
