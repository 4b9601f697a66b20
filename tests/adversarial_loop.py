# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The running loop for tests/test_adversarial.py: its processes, the attacker, the judgement.

``Loop`` starts the closed loop as processes from the one description (graph.closed_loop) with
either joint kind, ``Attacker`` is the rogue publisher and the listener in the test process,
``assert_recovered`` judges whether the loop tracks again after an attack (a loop that does not
is excused only by the host probe's stalls, tests/host_probe.py), and the log helpers read
rclpy's [LEVEL] [time] lines.
"""

import collections
import math
import re
import time
from pathlib import Path

from actuator_bringup.run_description import closed_loop, default_scenario
from actuator_bringup.runner import scenario_file
from actuator_bringup.supervisor import RosProcess, process_log
from actuator_core import limits
from actuator_core.timing import stamp_to_ns
from host_probe import HostWindow, skip_or_fail
from ros_helpers import TestNode, start_closed_loop

#: The joint kinds every attack runs against (graph.closed_loop's ``joint``).
JOINT_KINDS = ('plant', 'cia402_sim')
#: docs/safety.md#recovery-policy: after a 20-300 ms stall of the ESO or the controller the
#: loop tracks again with max |e| about 1.2e-3 rad (core model, fast deep-sea case; the real
#: loop measured 8.2e-4 to 2.6e-3).
DOCUMENTED_RECOVERED_ERROR_RAD = 1.2e-3
#: |e| of the controlled samples in the last second that counts as tracking again: within 3x
#: the documented figure [rad] (was 0.05 rad, which a joint 40x off the documented tracking
#: passed).
TRACKING_RAD = 3 * DOCUMENTED_RECOVERED_ERROR_RAD
#: Seconds after an attack by which a calm second must have come (see assert_recovered).
RECOVERY_DEADLINE_S = 20.0
#: A stamp gap longer than this ends a stretch of braked samples [ns]: the listener misses
#: samples, and a release and a new brake are a command timeout (10 ms) apart at least.
BRAKED_GAP_NS = 5 * 10**6


def _drive_brake_closing_ns() -> int:
    """Return the simulated drive's brake closing time [ns]: its EDS default of 0x2100."""
    import canopen

    from actuator_cia402 import profile
    from actuator_cia402.sim_drive_main import default_eds

    return int(canopen.import_od(default_eds())[profile.BRAKE_CLOSING_MS].default) * 10**6


#: After the torque went (effort 0), the simulated drive's brake is closed by then [ns]: its
#: closing time, and two 1 ms periods for the SYNC it began at and the sample's own.
DRIVE_BRAKE_CLOSED_AFTER_NS = _drive_brake_closing_ns() + 2 * 10**6
#: ControllerState statuses whose command is the law's (OK, RECOVERING).
CONTROLLED = (0, 9)
STATUS_CONFLICT, STATUS_LATCHED, STATUS_RESYNC = 7, 5, 6
#: Statuses that answer a stall (stale measurement, stale estimate, resync): in a second the
#: host kept on time there is none.
STALL_ANSWERS = (2, 3, STATUS_RESYNC)


class Loop:
    """The closed loop as processes, from the one description (graph.closed_loop).

    With restarts.
    """

    def __init__(self, env: dict, tmp: Path, joint: str):
        self.env, self.tmp, self.joint = env, tmp, joint
        #: the key of the joint's process: the plant, or the driver of the simulated drive
        self.joint_key = 'plant' if joint == 'plant' else 'driver'
        self.params = scenario_file(default_scenario(joint))  # what bringup --joint runs
        self.bag = tmp / 'bag'
        self.specs = {
            s.key: s
            for s in closed_loop(
                'realtime', 0.0, record=True, bag=self.bag, joint=joint, thread_priority=50
            )
        }
        self.starts: dict[str, int] = {}
        self.procs: dict[str, RosProcess] = start_closed_loop(
            self._process, self.specs.values(), self.params, on_start=drive_ready
        )

    def _process(self, package: str, executable: str, args: list, name: str) -> RosProcess:
        """Process of key ``name``, numbered by its start: every start's log is kept."""
        n = self.starts[name] = self.starts.get(name, 0) + 1
        return RosProcess.installed(
            package, executable, args, env=self.env, log_dir=self.tmp / 'logs', name=f'{name}{n}'
        )

    def start(self, key: str) -> RosProcess:
        self.procs[key] = start_closed_loop(self._process, [self.specs[key]], self.params)[key]
        return self.procs[key]

    def restart(self, key: str, pause_s: float = 0.5) -> None:
        """SIGINT the process (as Ctrl-C or a crash handler would), wait, start a new one."""
        assert self.procs[key].stop() == 0
        time.sleep(pause_s)
        self.start(key)

    def log(self, key: str) -> str:
        """Everything every process of ``key`` (the first and any restarted one) wrote."""
        return ''.join(
            process_log(self.tmp / 'logs', f'{key}{n}') for n in range(1, self.starts[key] + 1)
        )

    def stop(self) -> dict:
        return {k: p.stop() for k, p in reversed(list(self.procs.items()))}


def drive_ready(key: str, proc: RosProcess) -> None:
    """Wait until the simulated drive listens, before its driver configures (as the runner)."""
    if key == 'drive':
        proc.wait_for_output(r'^drive 1 ready$', timeout=30)


class Attacker(TestNode):
    """An rclpy node in the test process: the rogue publisher and the listener."""

    def __init__(self, context, joint: str):
        from sensor_msgs.msg import JointState

        from actuator_msgs.msg import ControllerState, CurrentCommand, PlantTruth, StateEstimate
        from actuator_ros.qos import control_qos

        super().__init__(context, 'attacker')
        self.joint = joint
        self.types = {
            'joint_states': JointState,
            'eso/estimate': StateEstimate,
            'current_command': CurrentCommand,
        }
        self.qos = control_qos('realtime')
        self.states: list = []
        self.truth: list = []
        self.node.create_subscription(
            ControllerState, 'controller/state', self.states.append, self.qos
        )
        self.node.create_subscription(PlantTruth, 'plant/truth', self.truth.append, self.qos)
        #: the joint's measurements (a rogue's own joint_states, which carry no effort, left out)
        self.measured: list = []
        self.node.create_subscription(
            JointState,
            'joint_states',
            lambda m: self.measured.append(m) if len(m.effort) == 1 else None,
            self.qos,
        )
        self.commands: list = []
        self.node.create_subscription(
            CurrentCommand, 'current_command', self.commands.append, self.qos
        )

    def wait_until_controlling(self, timeout: float = 60.0) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.spin(0.2)
            # the attacks stamp their messages with the newest measurement: one must be in
            if self.measured and sum(s.status in CONTROLLED for s in self.states[-200:]) > 150:
                return
        raise AssertionError('the loop never reached closed-loop control')

    def newest_stamp_ns(self) -> int:
        return stamp_to_ns(self.measured[-1].header.stamp)

    def joint_samples(self, after_ns: int = 0) -> list:
        """(stamp ns, position rad, braked, at rest) of the joint's samples received, by stamp.

        The plant's truth says its brake and velocity. A drive says neither per sample (its
        brake is bit 16 of 0x60FD, read over SDO at a stop): there braked is "no torque at the
        joint" (effort from 0x6077 exactly 0) and at rest "the position of the braked sample
        received before, the brake's closing time after the torque went" (the simulated drive's
        closed brake holds the joint exactly, as the plant's does; while it closes the joint
        slides without torque, and where its velocity turns it keeps one encoder count for a
        sample or two: taken for rest, that failed a CI run with 9 'moved' samples).
        """
        if self.joint == 'plant':
            out = [
                (
                    stamp_to_ns(t.header.stamp),
                    t.position_rad,
                    t.brake_engaged,
                    t.velocity_rad_s == 0.0,
                )
                for t in self.truth
            ]
            return sorted(x for x in out if x[0] > after_ns)
        out, previous, torque_gone_ns = [], None, None
        for m in sorted(self.measured, key=lambda m: stamp_to_ns(m.header.stamp)):
            stamp, position, braked = stamp_to_ns(m.header.stamp), m.position[0], m.effort[0] == 0
            within = previous is not None and stamp - previous[0] <= BRAKED_GAP_NS
            kept = previous is not None and previous[1:] == (position, True)
            # Without torque since: the first braked sample after one with torque, or after a
            # gap the joint moved across (the listener misses samples; a joint released and
            # braked again in a gap does not end at the encoder count it left).
            if braked and not (previous is not None and previous[2] and (within or kept)):
                torque_gone_ns = stamp
            # at rest: the brake closed, and the position of the braked sample received before
            closed = braked and stamp - torque_gone_ns >= DRIVE_BRAKE_CLOSED_AFTER_NS
            rest = closed and within and kept
            out.append((stamp, position, braked, rest))
            previous = (stamp, position, braked)
        return [x for x in out if x[0] > after_ns]

    def publisher(self, topic: str, matched: bool = True):
        """Create a rogue publisher; ``matched``: wait until every subscriber matched it."""
        pub = self.node.create_publisher(self.types[topic], topic, self.qos)
        end = time.monotonic() + 20.0
        while matched and time.monotonic() < end:
            wanted = self.node.count_subscribers(topic)  # the graph's view, this node included
            if wanted and pub.get_subscription_count() >= wanted:
                break
            self.spin(0.005)
        return pub


def last_states(attacker: Attacker, seconds: float = 1.0) -> list:
    """Return the states received whose stamps lie in the last ``seconds`` of stamps.

    By stamp, not by count: a listener on a loaded host receives a fraction of the 1 kHz states,
    and the last thousand received can reach back over a stall tens of seconds old.
    """
    if not attacker.states:
        return []
    newest = stamp_to_ns(attacker.states[-1].header.stamp)
    since = newest - int(seconds * 1e9)
    return [
        s for s in attacker.states[-int(seconds * 1000) :] if stamp_to_ns(s.header.stamp) > since
    ]


def tracking_again(attacker: Attacker, seconds: float = 1.0) -> float:
    """Max |e| of the controlled samples in the last ``seconds`` (inf when none was controlled)."""
    recent = last_states(attacker, seconds)
    errors = [
        abs(s.error_rad) for s in recent if s.status in CONTROLLED and math.isfinite(s.error_rad)
    ]
    return max(errors) if len(errors) > 0.5 * len(recent) else math.inf


def assert_recovered(running: Loop, attacker: Attacker):
    """No latched stop, control again, and a second tracking within TRACKING_RAD by the deadline.

    Judged from 3 s after the attack on; a later stall of this shared machine can cost another
    resync, so the loop gets until RECOVERY_DEADLINE_S to show one calm second. Safety holds on
    every run: no latch, and the law commands again (controlled samples in the last second).
    A last second outside TRACKING_RAD is excused only when the host probe's stalls account for
    its late commands and stall answers (host_probe.skip_or_fail: a skip after the caller's own
    safety assertions, which the caller makes first); otherwise it fails, naming the statuses
    and the logs' ends. Return None when it tracks, else the ``Unjudged`` figures for ``judge``.
    """
    attacker.spin(3.0)
    end = time.monotonic() + RECOVERY_DEADLINE_S - 3.0
    while tracking_again(attacker) >= TRACKING_RAD and time.monotonic() < end:
        assert 'safe stop latched' not in running.log('controller')
        attacker.spin(0.5)
    assert 'safe stop latched' not in running.log('controller')
    error = tracking_again(attacker)
    if error < TRACKING_RAD:
        print(f'\ntracking again: max |e| {error:.2e} rad of the last second')
        return None
    recent = last_states(attacker)
    assert recent, 'no controller state received at all'
    statuses = collections.Counter(s.status for s in recent)
    first, last = (stamp_to_ns(s.header.stamp) for s in (recent[0], recent[-1]))
    samples = max(1, round((last - first) / (limits.SAMPLE_TIME_S * 1e9)) + 1)
    late = recent[-1].late_samples - recent[0].late_samples
    stalls = sum(statuses[s] for s in STALL_ANSWERS)
    tails = {
        key: running.log(key).splitlines()[-8:] for key in ('controller', 'eso', running.joint_key)
    }
    said = '\n'.join(f'--- {key}:\n' + '\n'.join(lines) for key, lines in tails.items())
    figures = (
        f'max |e| {error:.2e} rad (bound {TRACKING_RAD:.2e}) {RECOVERY_DEADLINE_S:g} s after the '
        f'attack; in its last second {late} of {samples} commands late, statuses '
        f'{dict(statuses)} of {len(recent)} states received'
    )
    assert any(s.status in CONTROLLED for s in recent), (
        f'the law never ran again: {figures}\n{said}'
    )
    return Unjudged(f'{figures}\n{said}', late + stalls)


class Unjudged:
    """A recovery not seen: the loop's figures and its samples of trouble, for the host's say."""

    def __init__(self, figures: str, samples: int):
        self.figures, self.samples = figures, samples


def judge(host: HostWindow, unjudged) -> None:
    """End a test whose safety assertions passed: its recovery, or the host's excuse for it."""
    if unjudged is not None:
        skip_or_fail(host, unjudged.figures, samples=unjudged.samples)


def logged_after(log: str, text: str, after_s: float) -> bool:
    """Whether a log line containing ``text`` was written after wall time ``after_s``."""
    return logged_between(log, text, after_s, math.inf) > 0


def logged_between(log: str, text: str, after_s: float, before_s: float) -> int:
    """How many log lines containing ``text`` were written between wall times (s)."""
    count = 0
    for line in log.splitlines():
        match = re.match(r'\[\w+\] \[(\d+\.\d+)\]', line)
        count += bool(text in line and match and after_s < float(match.group(1)) < before_s)
    return count


def log_time_s(log: str, text: str) -> float:
    """Wall time [s] of the first log line containing ``text`` (rclpy's [LEVEL] [time] prefix)."""
    for line in log.splitlines():
        if text in line:
            match = re.match(r'\[\w+\] \[(\d+\.\d+)\]', line)
            if match:
                return float(match.group(1))
    raise AssertionError(f'no log line with {text!r}')
