# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The one description of a closed-loop run.

Which nodes, with which parameters and real-time settings. Both the runner (``bringup``,
actuator_bringup.runner) and the launch file (``actuator_bringup closed_loop.launch.py``) build
their processes from ``closed_loop``, so the two cannot drift apart (and ``composition.compose``
puts each joint's loop into one process). Pure data, no launch import: the runner has no launch
here.

Real-time settings are node parameters (actuator_ros.realtime), as ros2_control makes them:
``thread_priority`` (the ESO and controller at the given SCHED_FIFO priority, the plant or
driver one level above: it is the sampling hardware, and below them its tick queued behind
their callbacks: latency p99 1.51 -> 0.94 ms, 3 runs each way; the simulated CiA 402 drive one
above the driver, as hardware keeps its cycle), ``cpu_affinity`` and
``executor``. The recorder keeps normal scheduling: under SCHED_FIFO the real-time threads
exceeded the kernel's RT budget (sched_rt_runtime_us) and were stopped for 27-63 ms.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from actuator_sim.scenarios import DRIVE_HOLD_SCENARIO, HOLD_SCENARIO

#: What plays the joint: the simulated plant, the CiA 402 driver with its simulated drive on
#: a virtual CAN bus, the driver on a real bus, or nothing (a driver started elsewhere).
JOINTS = ('plant', 'cia402_sim', 'cia402', 'none')
#: The scenario each joint runs unless one is named: it holds still until a goal moves it
#: (reference ``hold``), with the paper's Case 2 tuning for the simulated plant (and a driver
#: started elsewhere); for a CiA 402 drive, whose RPDO acts one SYNC later, the same tuned for
#: that delay (``actuator_sim.scenarios.commanded``). The paper's cases run when named
#: (``case2_pp_nftsmc_eso``, as the main job does).
DEFAULT_SCENARIOS = {
    'plant': HOLD_SCENARIO,
    'cia402_sim': DRIVE_HOLD_SCENARIO,
    'cia402': DRIVE_HOLD_SCENARIO,
    'none': HOLD_SCENARIO,
}
#: ``bringup --pin`` on a 2-core machine: the ESO and the controller work in strict sequence
#: each sample (command -> estimate -> command), so they share a core; the joint uses the other.
#: A composed loop's process takes its joint's CPU (the first member's settings are the
#: process's): all its threads on one core, which under SCHED_FIFO cost 42-46 % of a core
#: against 57-60 % unpinned, latency p50 240-258 against 283-297 us (3 alternating pairs of 22 s
#: runs, 2026-12-05; docs/performance.md#current-figures has the benchmark's).
PINNING = {'joint': '0', 'eso': '1', 'controller': '1'}
#: Rate of the diagnostic topics (plant/truth, controller/state) in a real-time run that records
#: nothing [Hz]: enough for a live plot; a recorded or sim run keeps every sample for the analysis.
LIVE_DIAGNOSTICS_RATE_HZ = 100.0
#: Joints one run can put on one CAN bus (each its driver, ESO and controller under a namespace).
MAX_JOINTS_ON_BUS = 4
#: Seconds a bounded run's SYNC producer runs on past the others (see closed_loop).
SYNC_PRODUCER_GRACE_S = 2.0
#: Node id of the first joint's master (its heartbeat on 0x700 + id); joint i's is this - i + 1.
MASTER_NODE_ID = 127
#: The loop's topics of one joint (relative names: under a joint's namespace when there are more).
JOINT_TOPICS = ('joint_states', 'current_command', 'eso/estimate', 'controller/state')


@dataclass(frozen=True)
class NodeSpec:
    """One process of the run."""

    key: str  # plant | driver | eso | controller | recorder
    package: str
    executable: str
    name: str  # node name (parameter file sections are keyed by it)
    parameters: dict = field(default_factory=dict)
    scenario_file: bool = True  # gets the scenario's parameter file
    leader: bool = False  # the run ends when this process ends
    managed: bool = True  # a lifecycle node
    members: tuple = ()  # a container (``compose``): the nodes it runs, each a NodeSpec
    arguments: tuple = ()  # a plain process (no ROS node): its command line, e.g. the sim drive
    namespace: str = ''  # the node's namespace (several joints: joint1, joint2, ...)
    record_to: str = ''  # a container recording in-process (compose): its bag folder


def node_kind(spec: NodeSpec) -> str:
    """Return a spec's node kind: its key without a joint's number (controller2: controller)."""
    return spec.key.rstrip('0123456789')


def run_name(scenario: str, mode: str) -> str:
    """Return a run's name, its bag's and results' folder: <scenario>_<mode>_<UTC time>."""
    stamp = dt.datetime.now(dt.timezone.utc).strftime('%Y%m%dT%H%M%SZ')
    return f'{scenario}_{mode}_{stamp}'


def default_scenario(joint: str) -> str:
    """Return the scenario a run with ``joint`` gets when none is named (DEFAULT_SCENARIOS)."""
    if joint not in DEFAULT_SCENARIOS:
        raise ValueError(f'joint must be one of {", ".join(JOINTS)}, got {joint!r}')
    return DEFAULT_SCENARIOS[joint]


#: The recorder's niceness in real time (actuator_ros.realtime): under normal scheduling the
#: recorder (23-26 % of a core, 2026-12-05) competes with the loop's processes for two cores,
#: and the loop's samples wait for it; it has a queue of seconds, the loop a period.
RECORDER_NICE = 10


def recorder_parameters(mode: str) -> dict:
    """Return the recorder's queue for a closed-loop run in ``mode``.

    realtime: BEST_EFFORT, 5 s of queue per topic, at ``RECORDER_NICE``: the recorder keeps
    normal scheduling, and the queue rides out the bursts in which the SCHED_FIFO loop leaves it
    no CPU (measured, 3 runs each way: longest plant gap 17-43 ms -> 5-18 ms; a 1 s queue
    overflowed once, 8 % lost).
    sim: RELIABLE like the publishers, and 10 s of queue: the lockstep runs as fast as the CPU
    allows and does not wait for the recorder (2 s PI runs lost 68-669 of 2000 samples in 12
    of 94 runs with 1 s; 0 of 32 with 10 s).
    """
    if mode == 'sim':
        return {'reliability': 'reliable', 'queue_depth': 10000}
    return {'reliability': 'best_effort', 'queue_depth': 5000, 'nice': RECORDER_NICE}


def closed_loop(
    mode: str,
    duration_s: float,
    *,
    record: bool = True,
    bag: Optional[Path] = None,
    joint: str = 'plant',
    thread_priority: int = 0,
    cpus: Optional[dict] = None,
    executor: str = 'events',
    logs: Optional[Path] = None,
    joint_parameters: Optional[dict] = None,
    autostart: bool = True,
    live_view: bool = False,
    live_view_parameters: Optional[dict] = None,
    diagnostics_rate_hz: Optional[float] = None,
    joints: int = 1,
) -> list[NodeSpec]:
    """Return the processes of one run in start order.

    The joint is last: it starts sampling when all are there. ``logs``: folder for the per-node
    timing files the benchmark reads (controller_timing.npz, eso_stats.json, plant_samples.npz).
    ``autostart``: the nodes configure and activate themselves (the runner, and the launch file
    unless ``autostart:=false``); false: they wait for ``ros2 lifecycle set``. ``live_view``: also
    the Foxglove live view (actuator_live_view.live_view, ws://127.0.0.1:8765 unless
    ``live_view_parameters`` say otherwise), started before the joint so the joint waits for its
    subscription too.
    ``diagnostics_rate_hz``: the rate of controller/state and plant/truth (0: every sample); None:
    every sample when recording or in sim (the bag analysis needs them),
    ``LIVE_DIAGNOSTICS_RATE_HZ`` otherwise. ``joints`` > 1 (CiA 402 only): that many drives on one
    bus, node ids 1..n, each with its driver, ESO and controller under the namespace ``joint<i>``
    (keys ``driver<i>``, ``eso<i>``, ``controller<i>``); drive 1's driver produces the one SYNC,
    and every driver checks the bus load of all n.
    """
    _check_joints(joint, joints, live_view)
    common = _Common(executor, autostart, cpus or {}, logs)
    sim = mode == 'sim'
    namespaces = [''] if joints == 1 else [f'joint{i}' for i in range(1, joints + 1)]
    loop_params = {'mode': mode, 'use_sim_time': sim}
    if diagnostics_rate_hz is None:
        diagnostics_rate_hz = 0.0 if record or sim else LIVE_DIAGNOSTICS_RATE_HZ
    specs = []
    watchers = int(record) + int(live_view)  # readers of every loop topic beside the loop's
    if record:
        specs.append(_recorder(mode, bag, joints, namespaces))
    for ns in namespaces:
        specs += _estimator_and_controller(
            ns, loop_params, diagnostics_rate_hz, thread_priority, common, watchers
        )
    if live_view:
        specs.append(
            NodeSpec(
                'live_view',
                'actuator_live_view',
                'live_view',
                'live_view',
                {'executor': executor, **(live_view_parameters or {})},
                scenario_file=False,
                managed=False,
            )
        )
    joint_priority = min(thread_priority + 1, 99) if thread_priority else 0
    subscribers = 2 + watchers
    if joint == 'plant':
        specs.append(
            NodeSpec(
                'plant',
                'actuator_plant',
                'plant_node',
                'actuator_plant',
                {
                    'mode': mode,
                    'stop_after_s': float(duration_s),
                    'wait_for_subscribers': subscribers,
                    'truth_rate_hz': float(diagnostics_rate_hz),
                    **common.settings('joint', joint_priority),
                    **common.logged(('timing_log', 'plant_samples.npz')),
                },
                leader=True,
            )
        )
    elif joint in ('cia402_sim', 'cia402'):
        if sim:
            raise ValueError('the CiA 402 driver runs in real time only (mode realtime)')
        specs += _cia402(
            joint,
            joints,
            namespaces,
            duration_s,
            subscribers,
            joint_priority,
            joint_parameters,
            common,
        )
    return specs


def _check_joints(joint: str, joints: int, live_view: bool) -> None:
    """Refuse (ValueError) a joint kind, a number of joints or a live view a run cannot have."""
    if joint not in JOINTS:
        raise ValueError(f'joint must be one of {", ".join(JOINTS)}, got {joint!r}')
    if not 1 <= joints <= MAX_JOINTS_ON_BUS:
        raise ValueError(f'joints must be in [1, {MAX_JOINTS_ON_BUS}], got {joints}')
    if joints > 1 and joint not in ('cia402_sim', 'cia402'):
        raise ValueError(
            f'several joints share a CAN bus: joint cia402_sim or cia402, not {joint}'
        )
    if joints > 1 and live_view:
        raise ValueError('the live view shows one joint: run it with joints = 1')


@dataclass(frozen=True)
class _Common:
    """What every loop node of a run gets: executor, autostart, CPUs, the timing logs' folder."""

    executor: str
    autostart: bool
    cpus: dict
    logs: Optional[Path]

    def settings(self, key: str, priority: int) -> dict:
        """Return a node's executor, autostart and real-time parameters (``key``: its CPU)."""
        out = {'executor': self.executor, 'autostart': self.autostart}
        if priority:
            out['thread_priority'] = priority
        if key in self.cpus:
            out['cpu_affinity'] = self.cpus[key]
        return out

    def logged(self, name: tuple, ns: str = '') -> dict:
        """Return the timing log ``name`` (parameter, file) with its path in ``logs`` (or none)."""
        if self.logs is None:
            return {}
        stem, _, ext = name[1].rpartition('.')
        return {name[0]: str(self.logs / (f'{stem}_{ns}.{ext}' if ns else name[1]))}


def _keyed(key: str, ns: str) -> str:
    """Return a node's key in namespace ``ns`` (controller, joint2: controller2)."""
    return f'{key}{ns.removeprefix("joint")}'


def _named(ns: str) -> dict:
    """Return the joint name of a namespace (several joints: each its own, as in a URDF)."""
    return {'joint_name': ns} if ns else {}


def _recorder(mode: str, bag: Optional[Path], joints: int, namespaces: list[str]) -> NodeSpec:
    """Return the recorder's spec: every joint's loop topics, into ``bag`` if named."""
    topics = (
        {}
        if joints == 1
        else {
            'topics': [f'/{ns}/{topic}' for ns in namespaces for topic in JOINT_TOPICS],
        }
    )
    return NodeSpec(
        'recorder',
        'actuator_bag',
        'recorder',
        'recorder',
        {
            'use_sim_time': mode == 'sim',
            'record_diagnostics': True,
            **recorder_parameters(mode),
            **({'output': str(bag)} if bag else {}),
            **topics,
        },
        scenario_file=False,
        managed=False,
    )


def _estimator_and_controller(
    ns: str,
    loop_params: dict,
    diagnostics_rate_hz: float,
    thread_priority: int,
    common: _Common,
    watchers: int,
) -> list[NodeSpec]:
    """Return the controller's and the ESO's specs of the joint in namespace ``ns``.

    ``watchers``: the recorder and the live view, readers of every topic; with them, in sim, the
    controller holds its commands for the joint and the ESO, the ESO its estimates for the
    controller (``lockstep_subscribers``).
    """
    return [
        NodeSpec(
            _keyed('controller', ns),
            'actuator_controller',
            'controller_node',
            'actuator_controller',
            {
                **loop_params,
                'state_rate_hz': float(diagnostics_rate_hz),
                'lockstep_subscribers': 2 + watchers,
                **_named(ns),
                **common.settings('controller', thread_priority),
                **common.logged(('timing_log', 'controller_timing.npz'), ns),
            },
            namespace=ns,
        ),
        NodeSpec(
            _keyed('eso', ns),
            'actuator_eso',
            'eso_node',
            'actuator_eso',
            {
                **loop_params,
                'lockstep_subscribers': 1 + watchers,
                **_named(ns),
                **common.settings('eso', thread_priority),
                **common.logged(('stats_log', 'eso_stats.json'), ns),
            },
            namespace=ns,
        ),
    ]


def _cia402(
    joint: str,
    joints: int,
    namespaces: list[str],
    duration_s: float,
    subscribers: int,
    joint_priority: int,
    joint_parameters: Optional[dict],
    common: _Common,
) -> list[NodeSpec]:
    """Return the CiA 402 joints' specs: the simulated drive (cia402_sim), then the drivers."""
    from actuator_cia402.launch_spec import (
        DRIVER_EXECUTABLE,
        DRIVER_NODE_NAME,
        DRIVER_PACKAGE,
        SIM_DRIVE_EXECUTABLE,
        SIM_DRIVE_PACKAGE,
        driver_parameters,
        free_port,
        sim_drive_command,
    )

    specs = []
    simulated = joint == 'cia402_sim'
    overrides = dict(joint_parameters or {})
    sim_settings = {k: overrides.pop(k) for k in list(overrides) if k.startswith('sim.')}
    port = free_port() if simulated else 0
    drivers = []
    for node_id, ns in enumerate(namespaces, start=1):
        producer = node_id == 1
        params = driver_parameters(
            simulated=simulated,
            hub_port=port,
            node_id=node_id,
            # a bounded run: the SYNC producer outlives the consumers, so that none of them
            # loses its SYNC before its own end (the first to end ends the run)
            stop_after_s=float(duration_s)
            + (SYNC_PRODUCER_GRACE_S if joints > 1 and duration_s and producer else 0.0),
            wait_for_subscribers=subscribers,
            autostart=common.autostart,
            **(
                {}
                if joints == 1
                else {
                    'master_node_id': MASTER_NODE_ID - node_id + 1,
                    **_named(ns),
                    'sync_producer': producer,
                    'joints_on_bus': joints,
                }
            ),
            **overrides,
        )
        params.update(common.logged(('timing_log', 'plant_samples.npz'), ns))
        drivers.append(
            NodeSpec(
                _keyed('driver', ns),
                DRIVER_PACKAGE,
                DRIVER_EXECUTABLE,
                DRIVER_NODE_NAME,
                {**params, **common.settings('joint', joint_priority)},
                leader=True,
                namespace=ns,
            )
        )
    if simulated:  # the drive in a process of its own, as hardware: it outlives the driver
        specs.append(
            NodeSpec(
                'drive',
                SIM_DRIVE_PACKAGE,
                SIM_DRIVE_EXECUTABLE,
                SIM_DRIVE_EXECUTABLE,
                scenario_file=False,
                managed=False,
                arguments=tuple(
                    sim_drive_command(
                        port,
                        node_ids=tuple(range(1, joints + 1)),
                        sync_period_s=drivers[0].parameters['sample_time_s'],
                        # the simulated hardware above the software it serves
                        thread_priority=min(joint_priority + 1, 99) if joint_priority else 0,
                        **sim_settings,
                    )
                ),
            )
        )
    # The SYNC producer first, so it is stopped last (the runner stops in reverse order):
    # a consumer that lost its SYNC would end control with an error.
    return specs + drivers
