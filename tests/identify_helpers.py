# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Helpers of the identification tests (not collected): joints of known truth, and their bags.

``synthetic_joint`` runs a joint of the identified model's own family, q'' = theta1 i + theta2 q'
- fc sign(q') - fs exp(-(q'/vs)^2) sign(q') - fd q'|q'| + c, in a closed loop (a PD law with
acceleration feed-forward on the excitation reference), integrated by RK4 with the current held
over each 1 ms sample, its angle quantised as an encoder would. Every parameter's truth is then
exact. ``write_identification_bag`` writes such a run as the project's recorder or as
``ros2 bag record`` would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from actuator_analysis.identify import Record
from actuator_controller.excitation import ExcitationReference

DT_S = 1.0e-3
#: The PD law of the synthetic loop: natural frequency [rad/s] and damping, on a nominal theta1.
LOOP_RAD_S, LOOP_DAMPING, LOOP_THETA1 = 60.0, 0.9, 30.0


@dataclass
class Truth:
    """A joint of the model's family."""

    theta1: float = 25.0
    theta2: float = -8.0
    coulomb_rad_s2: float = 15.0
    offset_rad_s2: float = 2.0
    drag_per_rad: float = 0.5
    stribeck_rad_s2: float = 0.0
    stribeck_velocity_rad_s: float = 0.3
    #: theta1 (1 + a sin(w t)): a drifting joint (a, w [rad/s]); 0: constant.
    theta1_drift: tuple = (0.0, 0.0)

    def acceleration(self, t: float, v: float, i: float) -> float:
        """Return q'' of the joint."""
        a, w = self.theta1_drift
        sign = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
        friction = sign * (
            self.coulomb_rad_s2
            + self.stribeck_rad_s2 * math.exp(-((v / self.stribeck_velocity_rad_s) ** 2))
        )
        return (
            self.theta1 * (1.0 + a * math.sin(w * t)) * i
            + self.theta2 * v
            - friction
            - self.drag_per_rad * v * abs(v)
            + self.offset_rad_s2
        )


@dataclass
class JointRun:
    """What the synthetic loop recorded: per sample k, the angle and the current held before."""

    position_rad: np.ndarray  # measured (quantised)
    current_held_a: np.ndarray  # over the interval before sample k
    command_a: np.ndarray  # commanded at sample k (held over the interval after it)
    truth: Truth
    at_limit: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def record(self, name: str = 'synthetic') -> Record:
        """Return the run as one identification record."""
        return Record(DT_S, self.position_rad, self.current_held_a, self.at_limit, name)


def synthetic_joint(
    truth: Optional[Truth] = None,
    duration_s: float = 14.0,
    reference=None,
    counts_per_rev: float = 2.0**16,
    current_limit_a: float = 20.0,
) -> JointRun:
    """Run the joint in the PD loop on ``reference`` (default: the excitation)."""
    truth = truth or Truth()
    reference = reference or ExcitationReference()
    n = int(round(duration_s / DT_S))
    kp, kd = LOOP_RAD_S**2, 2.0 * LOOP_DAMPING * LOOP_RAD_S
    resolution = 2.0 * math.pi / counts_per_rev if counts_per_rev else 0.0
    q = v = 0.0
    y_prev = 0.0
    measured, held, command = np.empty(n), np.empty(n), np.empty(n)
    current = 0.0
    h = DT_S / 4
    for k in range(n):
        t = k * DT_S
        if k:  # integrate [t_k-1, t_k) with the current held
            for s in range(4):
                ts = t - DT_S + s * h
                a1 = truth.acceleration(ts, v, current)
                v2 = v + 0.5 * h * a1
                a2 = truth.acceleration(ts + 0.5 * h, v2, current)
                v3 = v + 0.5 * h * a2
                a3 = truth.acceleration(ts + 0.5 * h, v3, current)
                v4 = v + h * a3
                a4 = truth.acceleration(ts + h, v4, current)
                q += h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
                v += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        held[k] = current
        y = round(q / resolution) * resolution if resolution else q
        measured[k] = y
        r = reference.sample(t)
        speed = (y - y_prev) / DT_S if k else 0.0
        y_prev = y
        wanted = (
            r.acceleration_rad_s2 + kp * (r.position_rad - y) + kd * (r.velocity_rad_s - speed)
        )
        current = max(-current_limit_a, min(current_limit_a, wanted / LOOP_THETA1))
        command[k] = current
    at_limit = np.abs(held) >= current_limit_a
    return JointRun(measured, held, command, truth, at_limit)


#: The topics an identification bag may hold: kind -> (topic, type).
BAG_TOPICS = {
    'joint': ('/joint_states', 'sensor_msgs/msg/JointState'),
    'truth': ('/plant/truth', 'actuator_msgs/msg/PlantTruth'),
    'state': ('/controller/state', 'actuator_msgs/msg/ControllerState'),
    'command': ('/current_command', 'actuator_msgs/msg/CurrentCommand'),
    'estimate': ('/eso/estimate', 'actuator_msgs/msg/StateEstimate'),
}
#: k_t N the synthetic joint reports its effort with [N m/A], and the observer's theta1n.
TORQUE_PER_AMP, OBSERVER_THETA1N = 10.5, 31.4


def _messages(run: JointRun, store, kinds):
    """(kind, log time, message) per sample, stamps on a sim clock from 0."""
    types = store.types
    time_t, header_t = types['builtin_interfaces/msg/Time'], types['std_msgs/msg/Header']
    nan = float('nan')
    for k in range(len(run.position_rad)):
        ns = k * 1_000_000
        stamp = time_t(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        header = header_t(stamp=stamp, frame_id='')
        y, held, cmd = run.position_rad[k], run.current_held_a[k], run.command_a[k]
        if 'joint' in kinds:
            yield 'joint', ns + 10_000, types['sensor_msgs/msg/JointState'](
                header=header, name=['joint'], position=np.array([y]), velocity=np.empty(0),
                effort=np.array([TORQUE_PER_AMP * held]),
            )  # fmt: skip
        if 'truth' in kinds:
            fields = dict.fromkeys(
                ('position_rad', 'velocity_rad_s', 'acceleration_rad_s2', 'disturbance_rad_s2',
                 'parametric_rad_s2', 'stirring_rad_s2', 'external_rad_s2', 'seal_rad_s2',
                 'stirring_torque_nm', 'external_torque_nm', 'seal_torque_nm', 'inertia_kg_m2',
                 'torque_constant_nm_a', 'viscous_coefficient_nm_s_rad', 'viscosity_pa_s',
                 'pressure_pa', 'temperature_degc'),
                0.0,
            )  # fmt: skip
            yield (
                'truth',
                ns + 20_000,
                types['actuator_msgs/msg/PlantTruth'](
                    header=header, current_a=held, brake_engaged=False, **fields
                ),
            )
        if 'command' in kinds:
            yield (
                'command',
                ns + 30_000,
                types['actuator_msgs/msg/CurrentCommand'](
                    header=header, current_a=cmd, safe_stop=False
                ),
            )
        if 'estimate' in kinds:
            yield 'estimate', ns + 40_000, types['actuator_msgs/msg/StateEstimate'](
                header=header, position_rad=y, velocity_rad_s=0.0, disturbance_rad_s2=0.0,
                input_stamp=stamp, input_position_rad=y, input_current_a=held,
                input_current_gain=DT_S * OBSERVER_THETA1N, initial=k == 0,
                current_substituted=False, missing_current_count=0,
            )  # fmt: skip
        if 'state' in kinds:
            terms = dict.fromkeys(
                ('reference_position_rad', 'reference_velocity_rad_s',
                 'reference_acceleration_rad_s2', 'estimated_velocity_rad_s',
                 'estimated_disturbance_rad_s2', 'error_rad', 'rho_rad', 'lower_bound_rad',
                 'upper_bound_rad', 'z1', 'z2_rad_s', 'alpha_rad_s', 'alpha_dot_rad_s2',
                 'sigma_rad_s', 'u_eq_rad_s2', 'u_sw_rad_s2', 'u_b_rad_s2', 'proportional_a',
                 'integral_a'),
                nan,
            )  # fmt: skip
            yield 'state', ns + 50_000, types['actuator_msgs/msg/ControllerState'](
                header=header, controller_name='pd', measured_position_rad=y,
                bounds_kept=True, current_unlimited_a=cmd, current_a=cmd,
                saturated=bool(abs(cmd) >= 20.0), status=0, compute_time_s=1e-5,
                late_samples=0, missed_samples=0, **terms,
            )  # fmt: skip


def write_identification_bag(
    path: Path, run: JointRun, style: str = 'project', kinds=tuple(BAG_TOPICS)
) -> Path:
    """Write ``run`` as this project's recorder ('project') or ``ros2 bag record`` ('rosbag2')."""
    from actuator_bag.bag_format import BagWriter, QosProfile, topic_spec
    from bag_helpers import SOURCE

    store = SOURCE.typestore([BAG_TOPICS[k][1] for k in kinds])
    messages = sorted(_messages(run, store, kinds), key=lambda m: m[1])
    if style == 'project':
        with BagWriter(path) as writer:
            handles = {
                k: writer.add_topic(topic_spec(*BAG_TOPICS[k], SOURCE, [QosProfile(depth=100)]))
                for k in kinds
            }
            for kind, log_ns, msg in messages:
                writer.write(
                    handles[kind], log_ns, bytes(store.serialize_cdr(msg, BAG_TOPICS[kind][1]))
                )
        return path
    from rosbags.rosbag2 import StoragePlugin, Writer

    wall = 1_800_000_000_000_000_000  # ros2 bag record logs on the wall clock
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = {k: writer.add_connection(*BAG_TOPICS[k], typestore=store) for k in kinds}
        for kind, log_ns, msg in messages:
            writer.write(
                conns[kind], wall + log_ns, bytes(store.serialize_cdr(msg, BAG_TOPICS[kind][1]))
            )
    return path
