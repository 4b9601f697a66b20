# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The recovery policy at core level: stalls of the ESO or the controller, sample by sample.

``RealTimeModel`` runs the nodes' core objects as the real-time loop does, with what the
middleware does to a stalled node: its inputs queue (KEEP_LAST 10, the QoS of
actuator_ros.qos) and are delivered at once when it wakes; the drive's gate holds the last
command until its timeout and then brakes; the joint accepts commands through
``CommandBinding``. The controller's watchdog runs every sample on the monotonic clock. Each
stall is one deterministic run: after it, no more than a handful of samples at the current
limit, no latch, |e| back under 5e-3 rad within the time the policy states.
"""

from collections import deque

import numpy as np
import pytest

from actuator_controller.laws import make_controller
from actuator_controller.reference import make_reference
from actuator_core import limits
from actuator_core.assembly import RECOVERY_SAMPLES, RESYNC_SAMPLES, ControlSampleAssembly
from actuator_core.binding import CommandBinding
from actuator_core.gate import CommandGate
from actuator_core.pairing import ObserverInputPairing
from actuator_core.status import Status
from actuator_eso.observer import ExtendedStateObserver
from actuator_plant.model import JointPlant
from actuator_sim.loop import Scenario
from actuator_sim.scenarios import case2

pytestmark = pytest.mark.unit

P = 1_000_000
QUEUE = 10  # KEEP_LAST depth of the control topics
TIMEOUT_NS = int(limits.MEASUREMENT_TIMEOUT_S * 1e9)  # the controller's input timeouts
QUIET_NS = TIMEOUT_NS * 3 // 2  # the controller node's silence by design (controller_node)


class RealTimeModel:
    """Joint, ESO and controller objects wired as the real-time nodes are, with stalls."""

    def __init__(self, scenario: Scenario):
        """Build the objects of the three nodes (the ESO in its real-time configuration)."""
        dt = scenario.common.dt_s
        self.plant = JointPlant(scenario.plant, dt)
        self.eso = ExtendedStateObserver(scenario.eso, dt)
        self.pairing = ObserverInputPairing(self.eso, P, self.eso.correction, 1, 10)
        self.assembly = ControlSampleAssembly(
            make_controller(scenario.controller, scenario.gains, scenario.common),
            make_reference(scenario.reference),
            P,
        )
        self.gate = CommandGate(scenario.common.current_limit_a)
        self.gate.activate()
        self.binding = CommandBinding(P)
        self.gain = dt * scenario.eso.theta1n
        self.eso_inbox: deque = deque()
        self.controller_inbox: deque = deque()
        self.joint_outbox: list = []  # samples a stalled joint has not published yet
        self.joint_inbox: list = []  # commands a stalled joint has not read yet
        self.command_done = None  # when the controller last sent a command
        self.k = 0
        self.rows = []  # (k, applied current, brake, status, error)

    def _to_controller(self, kind, stamp, value):
        self.controller_inbox.append((kind, stamp, value))

    def _eso_publish(self, estimates):
        for e in estimates:
            self._to_controller('estimate', e.sample_ns, e)

    def _run_eso(self):
        while self.eso_inbox:
            kind, stamp, value = self.eso_inbox.popleft()
            if kind == 'y':
                self._eso_publish(self.pairing.add_measurement(stamp, value))
            else:
                self._eso_publish(self.pairing.add_command(stamp, value))

    def _run_controller(self, now):
        out = []
        while self.controller_inbox:
            kind, stamp, value = self.controller_inbox.popleft()
            if kind == 'y':
                if self.command_done is not None:  # the node's own silence (a stall of its own)
                    self.assembly.command_gap(now - self.command_done, QUIET_NS, now)
                out.append(self.assembly.add_measurement(stamp, value, now))
            else:
                e = value
                out.append(
                    self.assembly.add_estimate(
                        stamp,
                        e.x_hat[1],
                        e.x_hat[2],
                        e.input_ns,
                        e.input_current_a,
                        self.gain,
                        e.initial,
                        now,
                    )
                )
        out.append(self.assembly.watchdog(now + P // 2, TIMEOUT_NS, TIMEOUT_NS))
        out = [s for s in out if s is not None]
        if out:
            self.command_done = now
        return out

    @staticmethod
    def _keep_last(box: deque):
        """KEEP_LAST per topic: a stalled reader keeps the newest QUEUE of each kind."""
        for kind in {m[0] for m in box}:
            mine = [m for m in box if m[0] == kind]
            for m in mine[:-QUEUE]:
                box.remove(m)

    def _exchange(self, stamp, eso_stalled, controller_stalled, joint_stalled):
        """Run the awake nodes' rounds of sample ``stamp``; return the controller's samples."""
        samples = []
        for _ in range(3):  # estimates and commands ping-pong within the sample
            if not eso_stalled:
                self._run_eso()
            if not controller_stalled:
                new = self._run_controller(stamp)
                self.joint_inbox.extend(new)
                for s in new:
                    self.eso_inbox.append(('u', s.stamp_ns, s.current_a))
                samples += new
            if not joint_stalled:
                for s in self.joint_inbox:
                    if not self.binding.check(s.stamp_ns, s.safe_stop):
                        self.gate.offer(s.current_a, s.stamp_ns, s.safe_stop, stamp)
                self.joint_inbox.clear()
        return samples

    def step(self, eso_stalled=False, controller_stalled=False, joint_stalled=False):
        """Sample k: y(k) out, the awake nodes answer, the joint applies what it accepted.

        A stalled joint (the sim joint's sampling thread) replays its missed samples with the
        gate's hold and publishes them when it wakes; commands wait in its queue meanwhile.
        """
        stamp = self.k * P
        y = self.plant.position_rad
        self.binding.produced(stamp)
        self.joint_outbox.append(('y', stamp, y))
        if not joint_stalled:
            for box in (self.eso_inbox, self.controller_inbox):
                box.extend(self.joint_outbox)
                self._keep_last(box)  # a burst after a joint stall: the newest QUEUE stay
            self.joint_outbox.clear()
        samples = self._exchange(stamp, eso_stalled, controller_stalled, joint_stalled)
        for box, stalled in (
            (self.eso_inbox, eso_stalled),
            (self.controller_inbox, controller_stalled),
        ):
            if stalled:
                self._keep_last(box)
        if joint_stalled:
            del self.joint_inbox[:-QUEUE]
        held = self.gate.hold(stamp)
        self.plant.step(held.current_a, held.brake)
        law = [s for s in samples if s.output is not None]
        error = float(law[-1].output.error_rad) if law else float('nan')
        status = samples[-1].status if samples else None
        self.rows.append((self.k, held.current_a, held.brake, status, error))
        self.k += 1


def stall_run(node: str, stall_ms: int, at_ms: int = 2000, after_ms: int = 600):
    scenario = dict((s.name, s) for s, _ in case2(10.0))['case2_pp_nftsmc_eso']
    m = RealTimeModel(scenario)
    for k in range(at_ms + stall_ms + after_ms):
        stalled = at_ms <= k < at_ms + stall_ms
        m.step(
            eso_stalled=stalled and node == 'eso',
            controller_stalled=stalled and node == 'ctl',
            joint_stalled=stalled and node == 'joint',
        )
    return m


def summary(m: RealTimeModel, at_ms: int, stall_ms: int):
    rows = m.rows[at_ms:]
    at_limit = sum(abs(r[1]) >= limits.CURRENT_LIMIT_A - 1e-9 for r in rows)
    errors = np.array([r[4] for r in rows])
    end = at_ms + stall_ms
    recovered = [r[0] for r in m.rows[end:] if r[3] is Status.OK and abs(r[4]) < 5e-3]
    latched = any(r[3] is Status.LATCHED for r in rows)
    return at_limit, float(np.nanmax(np.abs(errors))), recovered[0] - end, latched


@pytest.mark.slow
def test_the_model_tracks_as_the_offline_loop_without_a_stall():
    m = stall_run('eso', 0, at_ms=1500, after_ms=0)
    errors = np.array([r[4] for r in m.rows[500:]])
    assert np.nanmax(np.abs(errors)) < 2e-3
    assert all(r[3] is Status.OK for r in m.rows[1:])


@pytest.mark.slow
@pytest.mark.parametrize('node', ['eso', 'ctl', 'joint'])
@pytest.mark.parametrize('stall_ms', [5, 8, 20, 60, 300])
def test_a_stall_ends_in_a_calm_recovery_never_a_chase(node, stall_ms):
    m = stall_run(node, stall_ms)
    at_limit, max_error, recover_ms, latched = summary(m, 2000, stall_ms)
    assert not latched
    assert at_limit <= 5, (at_limit, max_error, recover_ms)
    # recovered: at most the resync hold and the RECOVERING window after the stall
    assert recover_ms <= RESYNC_SAMPLES + RECOVERY_SAMPLES + 20, (at_limit, max_error, recover_ms)
    assert max_error < 5e-2, (at_limit, max_error, recover_ms)
    statuses = [r[3] for r in m.rows[2000:]]
    if stall_ms > 10:  # beyond the command timeout: the resync path, never the law's chase
        assert Status.RESYNC in statuses and Status.RECOVERING in statuses
    else:  # a short hiccup brakes nothing
        assert not any(r[2] for r in m.rows[2000:])


def cascade_run(seed: int, longest_ms: int, at_ms: int = 1000, total_ms: int = 3000):
    """Run the loop with the three nodes stalling at random from ``at_ms``, 1-``longest_ms`` ms."""
    rng = np.random.default_rng(seed)
    m = stall_run('eso', 0, at_ms=0, after_ms=0)
    left = {'eso': 0, 'ctl': 0, 'joint': 0}
    stalls = 0
    for k in range(total_ms):
        for node in left:
            if k >= at_ms and left[node] == 0 and rng.random() < CASCADE_STALL_RATE:
                left[node] = int(rng.integers(1, longest_ms + 1))
                stalls += 1
        m.step(left['eso'] > 0, left['ctl'] > 0, left['joint'] > 0)
        for node in left:
            left[node] = max(0, left[node] - 1)
    return m, stalls


#: Chance per sample and node that a stall starts in ``cascade_run``: 100-140 stalls in 2 s.
CASCADE_STALL_RATE = 0.02


@pytest.mark.slow
@pytest.mark.parametrize('seed', range(4))
def test_a_cascade_of_host_hiccups_shorter_than_the_input_timeouts_costs_no_current_spike(seed):
    """Stalls of 1-6 ms in the three nodes, 100-140 in 2 s: the drive holds the last command.

    Tells the timeouts apart: at 5 ms the watchdog's 0 A answers to these hiccups cost the
    joint its holding current and the law's catch-up reached the current limit (0-9 samples
    per run, max abs(e) up to 4.1e-3 rad); at limits.MEASUREMENT_TIMEOUT_S (7 ms) at most one
    sample, where two stalls chained into a gap beyond the timeout.
    """
    m, stalls = cascade_run(seed, longest_ms=6)
    rows = m.rows[1000:]
    assert stalls > 80
    assert sum(abs(r[1]) >= limits.CURRENT_LIMIT_A - 1e-9 for r in rows) <= 1
    # a brake only where an ESO and a controller stall chained beyond the command timeout
    assert m.assembly.resyncs <= 1
    assert sum(r[2] for r in rows) <= m.assembly.resyncs * (RESYNC_SAMPLES + 20)
    assert np.nanmax(np.abs([r[4] for r in rows])) < 3e-3


@pytest.mark.slow
@pytest.mark.parametrize('seed', range(8))
def test_a_cascade_of_stalls_around_the_command_timeout_never_latches_or_chases_long(seed):
    """Stalls of 1-12 ms in the three nodes: the longer ones end in the resync, none in a chase.

    The resyncs are the controller's own silence beyond the drive's timeout (``command_gap``),
    its inputs' gaps and the watchdog's brake (a joint replaying its samples shows no gap in
    the stamps). abs(e) stays under 5e-3 rad throughout: the restart onto the reference's first
    rest (``first_rest_s``); restarted at t = 0 instead, onto a reference already moving at
    -0.35 rad/s, 2 of these 8 runs passed it (5.1e-3, 1.2e-2 rad) and 4 more came within 5 %
    of it (4.8e-3 to 5.0e-3; at most 3.9e-3 with the restart at rest). Samples at the limit (0 in 7
    runs, 12 in one) are where the drive held a command through chained stalls.
    """
    m, stalls = cascade_run(seed, longest_ms=12)
    rows = m.rows[1000:]
    assert stalls > 80
    assert not any(r[3] is Status.LATCHED for r in rows)
    assert m.assembly.gap_resyncs > 0
    assert sum(abs(r[1]) >= limits.CURRENT_LIMIT_A - 1e-9 for r in rows) <= 15
    assert np.nanmax(np.abs([r[4] for r in rows])) < 5e-3
