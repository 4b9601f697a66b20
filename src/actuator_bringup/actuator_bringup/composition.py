# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A closed loop's joint, ESO and controller composed into one process (graph's processes in).

``compose`` turns ``graph.closed_loop``'s processes into the same run with each joint's loop in
one container process (actuator_bringup.container), as ROS 2 components are; the runner and the
launch file both call it.
"""

from __future__ import annotations

from actuator_bringup.run_description import NodeSpec, node_kind

#: The nodes a composed loop runs in one process, in the order they are built (the joint first:
#: its real-time settings are the process's), and the container's executable. The controller
#: before the ESO: one executor takes a sample's deliveries in that order, and the controller's
#: law needs y(k) at once while the ESO needs it only for x_hat(k+1) (measured, composed under
#: SCHED_FIFO, no recorder, 2 x 8 s each way: latency p50 284 / 277 us against 323 / 330 us).
COMPOSABLE = ('plant', 'driver', 'controller', 'eso')
#: The joints a composed loop can hold (the CiA 402 drive itself stays a process: hardware).
COMPOSABLE_JOINTS = ('plant', 'driver')
CONTAINER = ('actuator_bringup', 'loop_container')


def compose(specs: list[NodeSpec], record_in_process: bool = False) -> list[NodeSpec]:
    """Put each joint's joint, ESO and controller of ``specs`` into one process.

    The same nodes with the same parameters, on one executor (actuator_bringup.container); the
    recorder and the simulated drive (hardware) keep their own processes. Several joints: one
    container per joint, in its namespace, in the joints' order (the SYNC producer's first, so
    it is stopped last). Start order: the others, then the containers (each holds its joint,
    which starts sampling when all are there). ``record_in_process``: the container records
    the recorder's bag itself instead of the recorder process (``_in_process_bag`` says what
    that gives and keeps); a sim-time run of one joint only.
    """
    loops: dict[str, dict[str, NodeSpec]] = {}
    for spec in specs:
        if node_kind(spec) in COMPOSABLE:
            loops.setdefault(spec.namespace, {})[node_kind(spec)] = spec
    if not loops or any(not set(COMPOSABLE_JOINTS) & set(inside) for inside in loops.values()):
        raise ValueError(
            'a composed loop needs a joint of its own: the simulated plant or a CiA 402 driver'
        )
    bag = _in_process_bag(specs, loops) if record_in_process else ''
    if record_in_process:
        specs = [s for s in specs if s.key != 'recorder']
    containers = []
    for ns, inside in loops.items():
        members = tuple(inside[k] for k in COMPOSABLE if k in inside)
        containers.append(
            NodeSpec(
                f'loop{ns.removeprefix("joint")}',
                *CONTAINER,
                'loop_container',
                {},
                leader=any(m.leader for m in members),
                members=members,
                namespace=ns,
                record_to=bag,
            )
        )
    inside_keys = {m.key for c in containers for m in c.members}
    return [s for s in specs if s.key not in inside_keys] + containers


def _in_process_bag(specs: list[NodeSpec], loops: dict) -> str:
    """Return the bag folder a container records in-process, from the recorder's spec.

    Why a composed lockstep may record in-process (actuator_bag.tap): with the recorder process
    each of the loop's synchronous publishes also goes to another process (shared memory, a
    RELIABLE writer's bookkeeping per message), and the lockstep ran at 2.5-2.8x real time
    against 4.4x unrecorded; handed over a pipe in batches it runs at 3.8-4.3x
    (docs/performance.md#current-figures). It records what the container's nodes publish, not
    what other processes do.
    ValueError when the run cannot: without the recorder, more than one joint, or in real time,
    where a full pipe would hold up a loop that has a deadline (the recorder process records).
    """
    recorder = next((s for s in specs if s.key == 'recorder'), None)
    if recorder is None:
        raise ValueError('in-process recording records the run: it needs the recorder')
    if recorder.parameters.get('use_sim_time') is not True:
        raise ValueError(
            'in-process recording is for sim time: in real time a full pipe would hold up the '
            'loop; the recorder process records a real-time run'
        )
    if len(loops) != 1:
        raise ValueError('in-process recording records one joint')
    from actuator_bag.recording import default_output

    return str(recorder.parameters.get('output') or default_output())
