# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Helpers shared by the bag tests (not collected; checked by test_bag_helpers.py).

Synthetic run bags with the five system topics, and CurrentCommand payloads, written without ROS.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from actuator_bag.bag_format import BagWriter, QosProfile, topic_spec
from actuator_bag.msgdefs import DefinitionSource, definition_roots

REPO = Path(__file__).resolve().parents[1]
#: The repository's source folder holds actuator_msgs/msg/*.msg, so definitions resolve without
#: an install.
SOURCE = DefinitionSource(definition_roots([REPO / 'src']))

TOPICS = {
    'joint': ('/joint_states', 'sensor_msgs/msg/JointState'),
    'command': ('/current_command', 'actuator_msgs/msg/CurrentCommand'),
    'estimate': ('/eso/estimate', 'actuator_msgs/msg/StateEstimate'),
    'state': ('/controller/state', 'actuator_msgs/msg/ControllerState'),
    'truth': ('/plant/truth', 'actuator_msgs/msg/PlantTruth'),
}
T0_NS = 1_700_000_000_000_000_000
COMMAND_TYPE = TOPICS['command'][1]


@functools.cache
def _command_store():
    """Return the typestore of CurrentCommand (built once per process)."""
    return SOURCE.typestore([COMMAND_TYPE])


def command_cdr(
    nanosec: int, current_a: float, safe_stop: bool = False, sec: int = 1, frame_id: str = ''
) -> bytes:
    """CDR bytes of one CurrentCommand stamped (sec, nanosec)."""
    store = _command_store()
    types = store.types
    msg = types[COMMAND_TYPE](
        header=types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec),
            frame_id=frame_id,
        ),
        current_a=current_a,
        safe_stop=safe_stop,
    )
    return bytes(store.serialize_cdr(msg, COMMAND_TYPE))


def add_command_topic(writer: BagWriter, topic: str = '/current_command') -> int:
    """Add a CurrentCommand topic to an open writer; return its handle."""
    return writer.add_topic(topic_spec(topic, COMMAND_TYPE, SOURCE))


@dataclass
class SyntheticRun:
    """The arrays a synthetic run bag was written from.

    Tests compute the expected figures from them.
    """

    t: np.ndarray
    stamps_ns: np.ndarray
    reference: np.ndarray
    error: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    current: np.ndarray
    truth_velocity: np.ndarray
    truth_disturbance: np.ndarray
    est_velocity: np.ndarray
    est_disturbance: np.ndarray
    latency_ns: np.ndarray
    joint_stamps_ns: np.ndarray
    counts: dict[str, int] = field(default_factory=dict)
    #: The current the observer integrated per sample (None: the one held, ``current``).
    observer_input: Optional[np.ndarray] = None


def synthetic_run(
    duration_s: float = 8.0,
    dt_s: float = 1e-3,
    seed: int = 1,
    envelope: bool = True,
    violate_at: Optional[int] = None,
    drop_joint: tuple[int, ...] = (),
) -> SyntheticRun:
    """Arrays of a plausible tracking run.

    A decaying error inside a shrinking envelope, noisy estimates.
    """
    rng = np.random.default_rng(seed)
    n = int(round(duration_s / dt_s))
    t = np.arange(n) * dt_s
    stamps = T0_NS + np.arange(n, dtype=np.int64) * int(round(dt_s * 1e9))
    reference = 0.5 * np.sin(2 * np.pi * 0.25 * t) * (1 - np.exp(-t))
    rho = (0.05 - 0.002) * np.exp(-1.5 * t) + 0.002
    error = 0.02 * np.exp(-2.0 * t) * np.cos(7 * t) + 2e-4 * rng.standard_normal(n)
    error = np.clip(error, -0.9 * rho, 0.9 * rho)
    if violate_at is not None:
        error[violate_at] = 2.0 * rho[violate_at]
    lower = -rho if envelope else np.full(n, np.nan)
    upper = rho.copy() if envelope else np.full(n, np.nan)
    current = 1.5 * np.sin(2 * np.pi * 0.25 * t + 0.3) + 0.05 * rng.standard_normal(n)
    truth_velocity = np.gradient(reference + error, dt_s)
    truth_disturbance = -3.0 + 0.5 * np.sin(t)
    est_velocity = truth_velocity + 0.01 * rng.standard_normal(n)
    est_disturbance = truth_disturbance + 0.2 * rng.standard_normal(n)
    latency = (200_000 + rng.integers(0, 100_000, n)).astype(np.int64)
    keep = np.ones(n, dtype=bool)
    keep[list(drop_joint)] = False
    return SyntheticRun(
        t=t,
        stamps_ns=stamps,
        reference=reference,
        error=error,
        lower=lower,
        upper=upper,
        current=current,
        truth_velocity=truth_velocity,
        truth_disturbance=truth_disturbance,
        est_velocity=est_velocity,
        est_disturbance=est_disturbance,
        latency_ns=latency,
        joint_stamps_ns=stamps[keep],
    )


def run_messages(run: SyntheticRun, store, topics=tuple(TOPICS), controller='pp_nftsmc_eso'):
    """Yield (kind, log time, message) of a synthetic run, sample by sample."""
    types = store.types
    time_t, header_t = types['builtin_interfaces/msg/Time'], types['std_msgs/msg/Header']

    def header(ns: int):
        return header_t(
            stamp=time_t(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000)),
            frame_id='',
        )

    nan = float('nan')
    joint_stamps = set(run.joint_stamps_ns.tolist())
    observer_input = run.current if run.observer_input is None else run.observer_input
    for k, ns in enumerate(run.stamps_ns.tolist()):
        if ns in joint_stamps and 'joint' in topics:
            yield (
                'joint',
                ns + 50_000,
                types['sensor_msgs/msg/JointState'](
                    header=header(ns),
                    name=['joint'],
                    position=np.array([run.reference[k] + run.error[k]]),
                    velocity=np.empty(0),
                    effort=np.empty(0),
                ),
            )
        if 'estimate' in topics:
            yield (
                'estimate',
                ns + 60_000,
                types['actuator_msgs/msg/StateEstimate'](
                    header=header(ns),
                    position_rad=run.reference[k] + run.error[k],
                    velocity_rad_s=run.est_velocity[k],
                    disturbance_rad_s2=run.est_disturbance[k],
                    input_stamp=time_t(sec=0, nanosec=0),
                    input_position_rad=0.0,
                    input_current_a=observer_input[k],
                    input_current_gain=0.0,
                    initial=k == 0,
                    current_substituted=False,
                    missing_current_count=0,
                ),
            )
        if 'command' in topics:
            yield (
                'command',
                ns + int(run.latency_ns[k]),
                types['actuator_msgs/msg/CurrentCommand'](
                    header=header(ns), current_a=run.current[k], safe_stop=False
                ),
            )
        if 'state' in topics:
            yield (
                'state',
                ns + int(run.latency_ns[k]) + 1000,
                types['actuator_msgs/msg/ControllerState'](
                    header=header(ns),
                    controller_name=controller,
                    reference_position_rad=run.reference[k],
                    reference_velocity_rad_s=0.0,
                    reference_acceleration_rad_s2=0.0,
                    measured_position_rad=run.reference[k] + run.error[k],
                    estimated_velocity_rad_s=run.est_velocity[k],
                    estimated_disturbance_rad_s2=run.est_disturbance[k],
                    error_rad=run.error[k],
                    rho_rad=run.upper[k],
                    lower_bound_rad=run.lower[k],
                    upper_bound_rad=run.upper[k],
                    bounds_kept=bool(run.lower[k] < run.error[k] < run.upper[k]),
                    z1=nan,
                    z2_rad_s=nan,
                    alpha_rad_s=nan,
                    alpha_dot_rad_s2=nan,
                    sigma_rad_s=nan,
                    u_eq_rad_s2=nan,
                    u_sw_rad_s2=nan,
                    u_b_rad_s2=nan,
                    proportional_a=nan,
                    integral_a=nan,
                    current_unlimited_a=run.current[k],
                    current_a=run.current[k],
                    saturated=False,
                    status=0,
                    compute_time_s=1e-5,
                    late_samples=0,
                    missed_samples=0,
                ),
            )
        if 'truth' in topics:
            yield (
                'truth',
                ns + 40_000,
                types['actuator_msgs/msg/PlantTruth'](
                    header=header(ns),
                    position_rad=run.reference[k] + run.error[k],
                    velocity_rad_s=run.truth_velocity[k],
                    acceleration_rad_s2=0.0,
                    current_a=run.current[k],
                    disturbance_rad_s2=run.truth_disturbance[k],
                    parametric_rad_s2=0.0,
                    stirring_rad_s2=0.0,
                    external_rad_s2=0.0,
                    seal_rad_s2=0.0,
                    stirring_torque_nm=0.0,
                    external_torque_nm=0.0,
                    seal_torque_nm=0.0,
                    inertia_kg_m2=0.0,
                    torque_constant_nm_a=0.0,
                    viscous_coefficient_nm_s_rad=0.0,
                    viscosity_pa_s=0.0,
                    pressure_pa=0.0,
                    temperature_degc=0.0,
                    brake_engaged=False,
                ),
            )


def write_run_bag(
    path: Path,
    run: SyntheticRun,
    controller: str = 'pp_nftsmc_eso',
    topics: tuple[str, ...] = tuple(TOPICS),
    chunk_size: int = 1 << 20,
) -> Path:
    """Write a synthetic run as a bag with the given subset of the five system topics."""
    store = SOURCE.typestore([TOPICS[k][1] for k in topics])
    with BagWriter(path, chunk_size=chunk_size) as writer:
        handles = {
            k: writer.add_topic(
                topic_spec(TOPICS[k][0], TOPICS[k][1], SOURCE, [QosProfile(depth=100)])
            )
            for k in topics
        }
        for kind, log_ns, msg in run_messages(run, store, topics, controller):
            writer.write(handles[kind], log_ns, bytes(store.serialize_cdr(msg, TOPICS[kind][1])))
        run.counts = writer.summary().counts
    return path
