# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The running loop attacked as an adversarial user would.

The loop keeps tracking, or stops safely with the reason logged and resumes as the policy says
(docs/safety.md).

Each test runs the joint, ESO, controller and recorder in real time (SCHED_FIFO where the kernel
allows) on an isolated domain, attacks the loop from this process at about 3 s, and judges the
recorded run: no latched stop, the reason in the nodes' logs, and controlled samples tracking
again (|e| small) at the end. Every test runs against both joint kinds (issue 20): the simulated
plant, and the CiA 402 driver with the simulated drive in a process of its own
(``joint:=cia402_sim``). What the joint did is read from what both publish, joint_states (the
sample's stamp, position, and effort at the shaft: the plant's applied current, the drive's
torque actual value 0x6077); the plant's truth topic adds the brake flag and the velocity.
"""

import collections
import math
import os
import re
import signal
import time

import numpy as np
import pytest

from actuator_core import limits
from actuator_core.timing import stamp_to_ns
from actuator_ros.conversions import ns_to_stamp
from adversarial_loop import (
    BRAKED_GAP_NS,
    CONTROLLED,
    JOINT_KINDS,
    STATUS_CONFLICT,
    STATUS_LATCHED,
    STATUS_RESYNC,
    Attacker,
    Loop,
    assert_recovered,
    judge,
    log_time_s,
    logged_after,
    logged_between,
)
from host_probe import CIA402_LOOP, require_speed, skip_or_fail

pytestmark = [pytest.mark.realtime, pytest.mark.slow]


@pytest.fixture(params=JOINT_KINDS)
def loop(request, ros_env, rclpy_context, tmp_path):
    if request.param == 'cia402_sim':
        require_speed(CIA402_LOOP)
    running = Loop(ros_env, tmp_path, request.param)
    attacker = Attacker(rclpy_context, request.param)
    try:
        attacker.wait_until_controlling()
        yield running, attacker
    finally:
        attacker.close()
        codes = running.stop()
        assert all(c == 0 for c in codes.values()), codes
        assert not any('Traceback' in running.log(key) for key in running.specs)


#: A resync stamp starts a new episode after this long without one [ns].
EPISODE_GAP_NS = 20 * 10**6
#: The command that answers sample k acts from sample k + 1 on (plant/truth tells the brake over
#: the interval ending at its stamp); a late host adds a period or two [ns].
BRAKE_LAG_NS = 3 * 10**6
#: Share of resync samples with the brake engaged at the plant, at least.
BRAKE_HELD_MIN = 0.5


def _brake_in_resync(samples: list, resync: set) -> list:
    """Brake flags of the joint's samples at resync stamps, each episode's first BRAKE_LAG_NS out.

    ``samples``: Attacker.joint_samples.
    """
    starts, previous = [], None
    for stamp in sorted(resync):
        if previous is None or stamp - previous > EPISODE_GAP_NS:
            starts.append(stamp)
        previous = stamp
    held = []
    for stamp, _, braked, _ in samples:
        if stamp in resync:
            start = max(s for s in starts if s <= stamp)
            if stamp - start >= BRAKE_LAG_NS:
                held.append(braked)
    return held


#: Once at rest under the brake the joint stays where it stopped [rad]: the brake holds 50 N m,
#: above the external torque's 30 N m peak (docs/safety.md#command-gate-and-holding-brake), so the
#: simulated joint does not move at all. Before it is at rest it slides: from the fast trajectory's
#: 8.8 rad/s peak, up to 0.26 rad at the brake's 150 rad/s^2.
HELD_RAD = 1e-6
#: Braked samples at rest the listener gets after a restart, at least. A stopped ESO or
#: controller leaves the joint braked for the restart's pause and start-up (over 1 s: 700-4200
#: received here); a restarted joint is braked only until the controller's resync ends, and
#: this listener matches the new process late (1-52 received here): one, then.
BRAKED_AT_REST_MIN = {'joint': 1, 'eso': 100, 'controller': 100}


def _braked_stretches(samples: list) -> list:
    """Return the braked samples in stretches, none with a stamp gap over BRAKED_GAP_NS.

    ``samples``: Attacker.joint_samples (by stamp).
    """
    stretches, previous = [], None
    for sample in (x for x in samples if x[2]):
        if previous is None or sample[0] - previous > BRAKED_GAP_NS:
            stretches.append([])
        stretches[-1].append(sample)
        previous = sample[0]
    return stretches


def _held_offsets(stretches: list) -> list:
    """Return (stamp ns, position minus the rest position rad) of the braked samples at rest.

    Each stretch from its first sample at rest on; one never at rest gives none.
    """
    out = []
    for stretch in stretches:
        rest = next((x for x in stretch if x[3]), None)
        if rest is not None:
            out += [
                (stamp, position - rest[1])
                for stamp, position, _, _ in stretch
                if stamp >= rest[0]
            ]
    return out


def test_stamp_attacks_are_refused_with_their_reasons_and_tracking_goes_on(loop, host_window):
    """Estimates stamped ahead, in the past and twice, from the one publisher of the topic.

    The genuine observer is stopped first, so no second publisher stands and the conflict guard
    has no part in it: each refusal is the stamp rules' own. The observer then restarts and the
    loop tracks again.
    """
    running, attacker = loop
    assert running.procs['eso'].stop() == 0
    attacker.spin(0.3)  # the controller answers the missing estimates: 0 A and the brake
    attack_start, attack_start_s = len(attacker.states), time.time()
    est = attacker.publisher('eso/estimate')
    now = attacker.newest_stamp_ns()

    def send(stamp, velocity):
        e = attacker.types['eso/estimate'](
            velocity_rad_s=velocity, disturbance_rad_s2=2000.0, input_current_gain=0.03
        )
        e.header.stamp = ns_to_stamp(stamp)
        est.publish(e)
        attacker.spin(0.0005)

    send(now, 0.0)  # a well-stamped estimate for the newest measurement: the genuine one
    ahead = [now + (1000 + k) * 10**9 for k in range(100)]  # 100 estimates far ahead
    near = [now + k * 10**6 for k in range(5, 55)]  # a burst 5-54 ms ahead, for -20 A
    past = [now - 2 * 10**9, now - 10**6, now]  # 2 s back, one sample back, a duplicate
    for stamp in ahead + near + past:
        send(stamp, ROGUE_VELOCITY_RAD_S)
    attacker.spin(0.2)
    attacker.node.destroy_publisher(est)
    during = attacker.states[attack_start:]
    log = running.log('controller')
    # No second publisher stood: the guard neither logged one nor answered CONFLICT.
    assert not logged_after(log, '2 publishers on eso/estimate', attack_start_s)
    assert not any(s.status == STATUS_CONFLICT for s in during)
    # The first refusal line names one of the far-ahead stamps (the rate-limited log keeps the
    # first of each kind; a genuine estimate a lagging controller refused is another kind).
    far = {str(s) for s in ahead}
    first = next(
        (
            m
            for m in re.finditer(
                r'estimate stamped (\d+) ns refused: (\S+) ms ahead of the newest', log
            )
            if m.group(1) in far
        ),
        None,
    )
    assert first and float(first.group(2)) > 999_000.0, 'the far-ahead estimate was not refused'
    assert 'ms ahead of the newest measurement seen (at most 1 sample)' in log
    # None of the attack's estimates was used: no state carries its velocity.
    assert not any(s.estimated_velocity_rad_s == ROGUE_VELOCITY_RAD_S for s in attacker.states)
    running.start('eso')
    unjudged = assert_recovered(running, attacker)
    judge(host_window, unjudged)


#: The velocity the attacks' estimates carry [rad/s]: no state may ever show it.
ROGUE_VELOCITY_RAD_S = 7.77


def test_nan_and_absurd_values_in_each_field_are_refused(loop, host_window):
    running, attacker = loop
    est = attacker.publisher('eso/estimate')
    now = attacker.newest_stamp_ns()
    stamp = now + 2 * 10**6
    cases = (
        ('input_current_a', math.nan, limits.CURRENT_LIMIT_A),
        ('velocity_rad_s', 1.0e9, limits.VELOCITY_LIMIT_RAD_S),
        ('input_current_gain', 1.0e12, limits.input_current_gain_limit(limits.SAMPLE_TIME_S)),
        ('disturbance_rad_s2', math.inf, limits.DISTURBANCE_LIMIT_RAD_S2),
        ('disturbance_rad_s2', 1.0e5, limits.DISTURBANCE_LIMIT_RAD_S2),  # in range before
    )
    for field, value, _ in cases:
        e = attacker.types['eso/estimate'](input_current_gain=0.03)
        setattr(e, field, value)
        e.header.stamp = ns_to_stamp(stamp)
        est.publish(e)
        attacker.spin(1.1)  # one report per field and second (rate-limited log)
    attacker.node.destroy_publisher(est)
    unjudged = assert_recovered(running, attacker)
    log = running.log('controller')
    for field, value, bound in cases:
        assert (
            f'estimate for {stamp} ns refused: {field} = {value} is not finite or beyond '
            f'+-{bound:g}'
        ) in log
    judge(host_window, unjudged)


@pytest.mark.parametrize(
    'topic, watchers, guards',
    # watchers: the nodes that subscribe to the topic and name both publishers; guards: those
    # that see the second one when it matches (the controller polls its output at 10 Hz)
    [
        ('current_command', ('eso', 'controller', 'joint'), ('eso', 'joint')),
        ('joint_states', ('eso', 'controller'), ('eso', 'controller')),
        ('eso/estimate', ('controller',), ('controller',)),
    ],
)
def test_a_second_publisher_is_seen_when_it_matches_and_control_stops_safely(
    loop, topic, watchers, guards, host_window
):
    running, attacker = loop
    rogue = attacker.publisher(topic)  # matched everywhere before its first message
    sent, rogue_stamps = [], set()
    end = time.monotonic() + 0.6
    while time.monotonic() < end:  # a rogue script drives the topic for 0.6 s
        m = attacker.types[topic]()
        if topic == 'current_command':
            m.current_a = 5.0
        elif topic == 'eso/estimate':  # an estimate that would drive the joint hard
            m.velocity_rad_s, m.disturbance_rad_s2, m.input_current_gain = 5.0, 1000.0, 0.03
        else:
            m.name, m.position = ['joint'], [1.0]
        stamp = attacker.newest_stamp_ns()
        rogue_stamps.add(stamp)
        m.header.stamp = ns_to_stamp(stamp)
        rogue.publish(m)
        sent.append(time.time())
        attacker.spin(0.002)
    conflict = [s for s in attacker.states[-1000:] if s.status == STATUS_CONFLICT]
    assert conflict, 'the controller never reported the conflict'
    attacker.node.destroy_publisher(rogue)
    after_attack = len(attacker.states)
    unjudged = assert_recovered(running, attacker)
    # No chatter at the current limit once the conflict is over (Table 4's gains on the CiA 402
    # joint alternated +-20 A for 250-340 samples about 1.7 s after it, status OK throughout)
    at_limit = _at_limit(attacker.states[after_attack:])
    print(f'\n{topic} attack: {at_limit} received states at the current limit after it')
    text = f'2 publishers on {topic} ('
    for guard in watchers:
        log = running.log(running.joint_key if guard == 'joint' else guard)
        # The log names both publishers by GID (and by node once discovery knows the name:
        # at match time the attacker's is often still _NODE_NAME_UNKNOWN_).
        line = next(x for x in log.splitlines() if text in x)
        assert line.count(' gid ') == 2 and '/actuator_' in line, line
        if guard in guards:  # seen when it matched: before its second message was sent
            assert log_time_s(log, text) < sent[1], (log_time_s(log, text) - sent[0], guard)
    if topic == 'eso/estimate':  # none of the rogue's estimates reached the law
        assert not any(s.estimated_velocity_rad_s == 5.0 for s in attacker.states)
    if topic == 'current_command':  # the joint refused the rogue's 5 A, and said so
        joint_log = running.log(running.joint_key)
        assert f'{text}' in joint_log and 'refusing every command (0 A, brake)' in joint_log
        assert 'command refused: more than one publisher on current_command' in joint_log
    if conflict:
        # The brake holds over the conflict, from 20 ms after the first of the joint's own samples
        # answered CONFLICT (a rogue measurement's state carries the rogue's stamp, the newest
        # measurement this listener had: tens of ms old on a loaded host); no torque at the joint.
        own = [stamp_to_ns(s.header.stamp) for s in conflict]
        own = [stamp for stamp in own if stamp not in rogue_stamps]
        assert own, 'no sample of the joint answered CONFLICT'
        first, last = own[0] + 20 * 10**6, own[-1]
        braked = [x[2] for x in attacker.joint_samples(first - 1) if x[0] <= last]
        assert braked and all(braked)
        effort = [
            m.effort[0] for m in attacker.measured if first <= stamp_to_ns(m.header.stamp) <= last
        ]
        assert effort and not any(effort), max(effort, key=abs)
    if at_limit > AT_LIMIT_MAX:
        skip_or_fail(
            host_window,
            f'{at_limit} received states at the current limit after the attack',
            samples=at_limit,
        )
    judge(host_window, unjudged)


@pytest.mark.parametrize(
    'restarted_node, what',
    [
        # a restarted joint (plant or driver) starts a new time base at the wall clock's now
        ('joint', 'joint_states time base jumped'),
        # the restarted observer's first estimate (initial) resyncs the controller: its own line
        ('eso', 'the observer restarted or the time base jumped: resync'),
        ('controller', ''),
    ],
)
def test_a_restarted_node_resumes_control(loop, restarted_node, what, host_window):
    running, attacker = loop
    key = running.joint_key if restarted_node == 'joint' else restarted_node
    restarted = time.time()  # real-time stamps are wall-clock time
    running.restart(key)
    end = time.monotonic() + 60.0
    while (
        time.monotonic() < end
        and running.procs[key].running
        and 'active' not in running.procs[key].output
    ):
        attacker.spin(0.2)
    attacker.spin(2.0)
    unjudged = assert_recovered(running, attacker)
    if what:  # said for this restart, not for the start-up
        assert logged_after(running.log('controller'), what, restarted), what
    since = attacker.joint_samples(int(restarted * 1e9))
    # The joint was braked while control was down and through the resync, and held there: every
    # braked sample from the one at rest on is where that one was (before it, the joint slides
    # to a stop against the brake).
    at_rest = _held_offsets(_braked_stretches(since))
    assert len(at_rest) >= BRAKED_AT_REST_MIN[restarted_node], (
        f'{len(at_rest)} braked samples at rest after the restart (of {len(since)} received)'
    )
    print(f'braked at rest after the restart: {len(at_rest)} samples received')
    moved = [(stamp, offset) for stamp, offset in at_rest if abs(offset) > HELD_RAD]
    assert not moved, f'{len(moved)} of {len(at_rest)} braked samples moved: {moved[:10]}'
    resync = {stamp_to_ns(s.header.stamp) for s in attacker.states if s.status == STATUS_RESYNC}
    # every command answering a resync sample is 0 A with the brake (the controller's part)
    answers = [c for c in attacker.commands if stamp_to_ns(c.header.stamp) in resync]
    driving = [
        (stamp_to_ns(c.header.stamp), c.current_a, c.safe_stop)
        for c in answers
        if not (c.safe_stop and c.current_a == 0.0)
    ]
    assert not driving, (len(answers), driving[:10])
    if key != 'controller':  # the brake holds while the controller resyncs
        held = _brake_in_resync(attacker.joint_samples(), resync)
        # The plant's part: a late host delays some of those commands past the sample they
        # were for; a joint whose brake the resync commands released would show next to none
        # (before the assembly kept a safe stop's brake, its watchdog's 'no brake yet' answer
        # released it: 85 % held on one run). (The 10-deep best-effort listener of a loaded
        # test process may miss a whole episode.)
        assert not held or np.mean(held) > BRAKE_HELD_MIN, (sorted(resync), held)
    judge(host_window, unjudged)


#: Stall lengths [s] (issue 21): each node is stopped (SIGSTOP) this long, in turn.
STALLS_S = (0.005, 0.02, 0.06, 0.3)
#: Samples at the current limit a stall may cost at most ("a handful"). More than this in the
#: second before a stall means the loop, not the stall, was at the limit: seen through the
#: simulated drive with Table 4's gains (a growing 12 ms oscillation to +-20 A, status OK
#: inside the envelope), before the CiA joints got the tuning for the drive's delay
#: (drive_pp_nftsmc_eso, docs/cia402.md#tuned-for-the-drives-delay).
AT_LIMIT_MAX = 5
#: After a stall |e| is back under this [rad] within RECOVER_S: the resync hold (50 ms) plus
#: the RECOVERING window (50 ms) plus the stall's own backlog, with margin for a loaded host.
RECOVERED_RAD = 5e-3
RECOVER_S = 0.3
#: Received controlled samples in a row under RECOVERED_RAD that make the recovery (the 10-deep
#: best-effort listener of the test keeps a third or more of the 1 kHz states).
RECOVERED_SAMPLES = 30
#: Resyncs one stall makes at most (its gap and the observer's restart); more are a trouble the
#: host probe must account for (seen here on a loaded run: 4 within 150 ms of a 5 ms stall).
RESYNCS_PER_STALL = 2
#: Both resync warnings end so (a gap, the node's own stall, or an observer restart).
RESYNC_LINE = 'resync, 0 A and brake while the observer converges'


def _recovered_after_s(errors: list, resumed_ns: int) -> float:
    """Time [s] from ``resumed_ns`` to the first controlled sample that starts a calm stretch.

    ``errors``: (stamp ns, |e| rad) of the controlled samples received. Calm: it and the next
    RECOVERED_SAMPLES received are all under RECOVERED_RAD (a later, separate stall of the host
    is not this stall's recovery); inf when no such stretch came.
    """
    after = [(t, e) for t, e in errors if t > resumed_ns]
    for i, (t, _) in enumerate(after):
        stretch = after[i : i + RECOVERED_SAMPLES]
        if len(stretch) == RECOVERED_SAMPLES and all(e < RECOVERED_RAD for _, e in stretch):
            return (t - resumed_ns) / 1e9
    return math.inf


def _at_limit(states: list) -> int:
    """How many of ``states`` commanded the current limit (either sign)."""
    return sum(abs(s.current_a) >= limits.CURRENT_LIMIT_A - 1e-9 for s in states)


@pytest.mark.parametrize('key', ['eso', 'controller'])
def test_a_stalled_node_ends_in_a_calm_recovery(loop, key, host_window):
    running, attacker = loop
    proc = running.procs[key]
    table, unjudged = [], []
    for stall_s in STALLS_S:
        before = len(attacker.states)
        attacker.spin(1.0)
        mark = len(attacker.states)
        calm = _at_limit(attacker.states[before:mark])
        # the controller's own count of late commands over that second
        late_before = (
            attacker.states[mark - 1].late_samples - attacker.states[before].late_samples
            if mark > before
            else 0
        )
        os.killpg(proc.pid, signal.SIGSTOP)
        stopped = time.time()
        time.sleep(stall_s)
        os.killpg(proc.pid, signal.SIGCONT)
        resumed_ns = int(time.time() * 1e9)
        attacker.spin(1.5)
        after = attacker.states[mark:]
        # resyncs the controller logged meanwhile: one stall makes one or two (its gap and the
        # observer's restart); more are stalls of the host around it
        resyncs = logged_between(running.log('controller'), RESYNC_LINE, stopped, time.time())
        at_limit = _at_limit(after)
        errors = [
            (stamp_to_ns(s.header.stamp), abs(s.error_rad))
            for s in after
            if s.status in CONTROLLED and math.isfinite(s.error_rad)
        ]
        recover_s = _recovered_after_s(errors, resumed_ns)
        # the controller's own count of late commands, less those the stall itself delayed
        host_late = after[-1].late_samples - after[0].late_samples - round(stall_s * 1e3)
        max_e = max((e for _, e in errors), default=0.0)
        table.append((key, stall_s, at_limit, max_e, recover_s, max(host_late, 0), resyncs, calm))
        statuses = collections.Counter(s.status for s in after)
        detail = (table, dict(statuses), running.log('controller').splitlines()[-6:])
        assert not statuses[STATUS_LATCHED], detail
        if calm > AT_LIMIT_MAX or at_limit > AT_LIMIT_MAX or recover_s > RECOVER_S:
            # Excused at the end only by the host probe: its stalls must account for the
            # samples of trouble around this stall (late commands in the second before it and
            # beyond the stall's own after it, samples at the limit, the resyncs beyond the
            # stall's own at 50 samples each).
            trouble = max(late_before, 0) + max(host_late, 0) + calm + at_limit
            unjudged.append((stall_s, trouble + 50 * max(resyncs - RESYNCS_PER_STALL, 0)))
            continue
        if stall_s > limits.COMMAND_TIMEOUT_S:  # the joint was braked: a resync, logged
            assert logged_after(running.log('controller'), RESYNC_LINE, stopped), detail
    log = running.log('controller')
    assert 'RECOVERING: the law runs again after a gap or a resync' in log
    # a stalled controller finds the gap itself; a stalled ESO restarts and says so first
    assert RESYNC_LINE in log, table
    print(
        '\nstall table (node, stall s, samples at the limit, max |e| rad, recovered after s, '
        'late commands of the host, resyncs logged, samples at the limit in the second before):'
    )
    for row in table:
        print('  %-10s %5.3f %4d %9.2e %6.3f %5d %3d %4d' % row)
    if unjudged:
        skip_or_fail(
            host_window,
            f'stalls not recovered calmly (no latch): {unjudged} (stall s, samples of trouble); '
            f'the table: {table}',
            samples=sum(samples for _, samples in unjudged),
        )
