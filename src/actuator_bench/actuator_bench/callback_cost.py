# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""What one sample costs in each node's callbacks, in this process, without the middleware.

    python -m actuator_bench.callback_cost [--samples 5000] [--json FILE]

The joint (plant node, sim mode), the ESO and the controller are built as they run, and
their publishers are wired to each other's callbacks through a FIFO (the order DDS delivers in
one process): the deterministic sim lockstep with the middleware taken out. The nodes publish
CDR bytes (actuator_ros.wire), so each hop's encoding and decoding, our Python, is counted; the
middleware's own conversion and delivery are not. Each callback is
timed (perf_counter_ns); the figures are medians per sample and per node, and the chain's
samples per wall second. The run's commands are checked against the offline loop bit for bit,
so the figures are those of the real path. The difference to a composed run's speed is the
middleware's share.
"""

from __future__ import annotations

import argparse
import collections
import json
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from actuator_sim.scenarios import PAPER_SCENARIO

SCENARIO = PAPER_SCENARIO


def _wire(nodes: dict, queue: collections.deque, listened: bool = True) -> None:
    """Replace each publisher's publish by a hand-over to the subscribers' callbacks.

    The diagnostic topics (plant/truth, controller/state) go nowhere; ``listened`` says whether
    a subscriber is there (a recorder: they are filled each sample) or not (they are skipped).
    A subscriber's decoding of the bytes is counted in its callback, as in its subscription.
    """
    from sensor_msgs.msg import JointState

    from actuator_msgs.msg import CurrentCommand, StateEstimate
    from actuator_ros.wire_io import codec

    plant, eso, ctrl = nodes['joint'], nodes['eso'], nodes['controller']

    def taking(callback, cls):
        decode = codec(cls).decode
        return lambda data: callback(decode(data))

    routes = {
        (plant, 'state_pub'): [
            ('eso', taking(eso.on_measurement, JointState)),
            ('controller', taking(ctrl.on_measurement, JointState)),
        ],
        (eso, 'pub'): [('controller', taking(ctrl.on_estimate, StateEstimate))],
        (ctrl, 'cmd_pub'): [
            ('eso', taking(eso.on_command, CurrentCommand)),
            ('joint', taking(plant.on_command, CurrentCommand)),
        ],
    }
    quiet = [(plant, 'truth_pub'), (plant, 'clock_pub'), (ctrl, 'state_pub')]
    for (node, attr), targets in routes.items():
        getattr(node, attr).publish = lambda msg, t=targets: queue.extend(
            (k, f, msg) for k, f in t
        )
    for node, attr in quiet:
        getattr(node, attr).publish = lambda msg: None
        getattr(node, attr).get_subscription_count = lambda: int(listened)


def measure(samples: int, listened: bool = True) -> dict:
    """Run ``samples`` samples through the wired nodes; return the per-node medians [us].

    ``listened``: the diagnostic topics have a subscriber (as in a recorded run).
    """
    import rclpy

    from actuator_bringup.runner import scenario_file
    from actuator_controller.controller_node import ControllerNode
    from actuator_eso.eso_node import EsoNode
    from actuator_msgs.msg import CurrentCommand
    from actuator_plant.plant_node import PlantNode
    from actuator_ros.wire_io import codec
    from actuator_sim.loop import ClosedLoop
    from actuator_sim.params_yaml import all_scenarios

    scenario = all_scenarios()[SCENARIO]
    args = ['--ros-args', '--log-level', 'warn', '--params-file', str(scenario_file(SCENARIO))]
    for name in ('actuator_plant', 'actuator_eso', 'actuator_controller'):
        args += ['-p', f'{name}:mode:=sim']
    for name in ('actuator_eso', 'actuator_controller'):
        args += ['-p', f'{name}:use_sim_time:=true']
    rclpy.init(args=args)
    try:
        plant, eso, ctrl = PlantNode(), EsoNode(), ControllerNode()
        nodes = {'joint': plant, 'eso': eso, 'controller': ctrl}
        for node in nodes.values():
            node.trigger_configure()
            node.trigger_activate()
        queue: collections.deque = collections.deque()
        _wire(nodes, queue, listened)
        per_node = {key: np.zeros(samples + 1, dtype=np.int64) for key in nodes}
        commands: list[float] = []
        publish, read = ctrl.cmd_pub.publish, codec(CurrentCommand).decode

        def publish_keeping(data) -> None:  # the command's current kept, then published
            commands.append(read(data).current_a)
            publish(data)

        ctrl.cmd_pub.publish = publish_keeping
        start = time.perf_counter_ns()
        plant._start_sampling()  # publishes sample 0: the chain runs from the queue
        while queue and plant.sample_index < samples:
            key, callback, msg = queue.popleft()
            t0 = time.perf_counter_ns()
            callback(msg)
            per_node[key][plant.sample_index] += time.perf_counter_ns() - t0
        wall_s = (time.perf_counter_ns() - start) * 1e-9
        for node in nodes.values():
            node.halt()
            node.destroy_node()
    finally:
        rclpy.shutdown()
    scenario.duration_s = samples * scenario.common.dt_s
    offline = ClosedLoop(scenario).run(stop_on_divergence=False)
    n = min(len(commands), samples)
    return {
        'samples': n,
        'identical_to_offline': bool(np.array_equal(commands[:n], offline['current_a'][:n])),
        'median_us': {k: float(np.median(v[1:n])) / 1e3 for k, v in per_node.items()},
        'samples_per_wall_s': n / wall_s,
        'real_time_factor': n * scenario.common.dt_s / wall_s,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Print the callback costs of one sample per node."""
    parser = argparse.ArgumentParser(prog='callback_cost', description=__doc__.splitlines()[0])
    parser.add_argument('--samples', type=int, default=5000)
    parser.add_argument('--json', type=Path, help='write the figures as JSON')
    parser.add_argument(
        '--unlistened',
        action='store_true',
        help='no subscriber on plant/truth and controller/state (a run that records nothing)',
    )
    args = parser.parse_args(argv)
    figures = measure(args.samples, listened=not args.unlistened)
    for key, us in figures['median_us'].items():
        print(f'{key:10s} {us:7.1f} us per sample (median of its callbacks)')
    print(
        f'chain      {figures["samples_per_wall_s"]:7.0f} samples/s = '
        f'{figures["real_time_factor"]:.2f}x real time without the middleware; '
        f'identical to the offline loop: {figures["identical_to_offline"]}'
    )
    if args.json:
        args.json.write_text(json.dumps(figures, indent=1))
    return 0 if figures['identical_to_offline'] else 1


if __name__ == '__main__':
    raise SystemExit(main())
