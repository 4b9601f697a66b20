# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The drive gate and the stamp check at their boundaries, with exact results and messages.

Written against the surviving mutants of ``make mutation`` (docs/mutation-report.md): each test
tells apart behaviours the protocol tests did not (a limit taken as < or <=, a counter not
reset, a message that said less).
"""

from __future__ import annotations

import numpy as np
import pytest

from actuator_core import limits
from actuator_core.gate import CommandGate, Held
from actuator_core.timebase import JUMP_SAMPLES, StampCheck, Verdict

P = 1_000_000  # 1 ms in ns


def active_gate(**kwargs) -> CommandGate:
    """Return an activated gate."""
    gate = CommandGate(**kwargs)
    gate.activate()
    return gate


# ------------------------------------------------------------------------------- CommandGate
def test_gate_defaults_are_the_one_limit_and_timeout() -> None:
    """The defaults come from limits.py; a fresh gate is inactive with the brake engaged."""
    gate = CommandGate()
    assert gate.current_limit_a == limits.CURRENT_LIMIT_A
    assert gate.timeout_ns == round(limits.COMMAND_TIMEOUT_S * 1e9) == 10 * P
    assert (gate.active, gate.brake, gate.refused, gate.timeouts) == (False, True, 0, 0)


def test_gate_takes_any_positive_limit_and_converts_the_timeout_exactly() -> None:
    """A limit below 1 A is valid; a 1 s timeout is 10^9 ns, to the nanosecond."""
    gate = active_gate(current_limit_a=0.5, timeout_s=1.0)
    assert gate.timeout_ns == 10**9
    assert gate.offer(0.5, 0, False, 0) is None and gate.hold(10**9).current_a == 0.5
    assert gate.hold(10**9 + 1).reason == 'command timeout'


def test_the_first_timeout_of_a_fresh_gate_is_counted() -> None:
    """No hold in time before it: the first silence is still one timeout."""
    gate = active_gate()
    gate.offer(1.0, 0, False, 0)
    assert gate.hold(20 * P).reason == 'command timeout' and gate.timeouts == 1


@pytest.mark.parametrize(
    'kwargs, message',
    [
        ({'current_limit_a': 0.0}, 'current_limit_a must be finite and > 0, got 0.0'),
        ({'current_limit_a': float('inf')}, 'current_limit_a must be finite and > 0, got inf'),
        ({'timeout_s': 0.0}, 'timeout_s must be finite and > 0, got 0.0'),
        ({'timeout_s': float('nan')}, 'timeout_s must be finite and > 0, got nan'),
        ({'brake_delay_s': -0.001}, 'brake_delay_s must be finite and >= 0, got -0.001'),
        ({'brake_delay_s': float('inf')}, 'brake_delay_s must be finite and >= 0, got inf'),
    ],
)
def test_gate_refuses_a_bad_configuration_with_its_reason(kwargs: dict, message: str) -> None:
    """A zero, infinite or NaN limit or timeout, a negative or infinite brake delay: raises."""
    with pytest.raises(ValueError) as err:
        CommandGate(**kwargs)
    assert str(err.value) == message


def test_gate_accepts_exactly_the_limit_and_refuses_beyond_it_with_the_exact_message() -> None:
    """|u| = limit passes in either sign; just above gives the one-line refusal and 0 A, brake."""
    gate = active_gate(current_limit_a=2.0)
    assert gate.offer(2.0, 0, False, 0) is None and gate.hold(0) == Held(2.0, 0, False, '')
    assert gate.offer(-2.0, P, False, P) is None and gate.hold(P).current_a == -2.0
    message = gate.offer(2.5, 2 * P, False, 2 * P)
    assert message == 'command 2.5 A refused (valid: finite, |u| <= 2 A); applying 0 A'
    assert gate.hold(2 * P) == Held(0.0, -1, True, 'safe stop') and gate.refused == 1
    assert gate.brake is True  # the gate's own state says so too, not only what it holds
    assert gate.offer(float('-inf'), 3 * P, False, 3 * P).startswith('command -inf A refused')
    assert gate.refused == 2


def test_a_refused_command_restarts_the_timeout_and_a_valid_one_releases_the_brake() -> None:
    """After a refusal the drive brakes (no timeout counted); the next valid command drives."""
    gate = active_gate()
    gate.offer(1.0, 0, False, 0)
    gate.offer(float('nan'), P, False, 5 * P)
    assert gate.hold(5 * P + 10 * P).reason == 'safe stop' and gate.timeouts == 0
    assert gate.offer(3.0, 6 * P, False, 6 * P) is None
    assert gate.hold(6 * P) == Held(3.0, 6 * P, False, '') and not gate.brake


def test_each_timeout_is_counted_once_and_again_after_commands_resumed() -> None:
    """Two separate silences: two timeouts, however often each is held."""
    gate = active_gate(timeout_s=0.005, brake_delay_s=0.0)
    gate.offer(1.0, 0, False, 0)
    assert gate.hold(5 * P).current_a == 1.0  # exactly the timeout old: still applied
    for k in range(6, 9):
        assert gate.hold(k * P) == Held(0.0, -1, True, 'command timeout')
    assert gate.timeouts == 1 and gate.brake
    gate.offer(1.5, 9 * P, False, 9 * P)
    assert gate.hold(9 * P) == Held(1.5, 9 * P, False, '')
    gate.hold(20 * P)
    assert gate.timeouts == 2


def test_activation_forgets_the_last_command_and_deactivation_brakes() -> None:
    """A command from before a deactivate/activate cycle is never applied again."""
    gate = active_gate()
    gate.offer(4.0, 0, False, 0)
    gate.deactivate()
    assert (gate.active, gate.brake) == (False, True)
    assert gate.offer(4.0, P, False, P) == 'the drive is not active'
    gate.activate()
    assert gate.hold(P) == Held(0.0, -1, True, 'no command yet')


def test_a_safe_stop_keeps_the_brake_until_a_command_without_it() -> None:
    """safe_stop: 0 A whatever the current, brake on; the next plain command releases it."""
    gate = active_gate()
    assert gate.offer(7.0, 0, True, 0) is None
    assert gate.hold(0) == Held(0.0, 0, True, 'safe stop') and gate.brake
    gate.offer(7.0, P, False, P)
    assert gate.hold(P) == Held(7.0, P, False, '')


def test_a_batch_refuses_element_by_element() -> None:
    """Arrays (offline batches): each refused element gets 0 A, the rest are applied as sent."""
    gate = active_gate(current_limit_a=2.0)
    currents = np.array([1.0, 2.0, 2.5, np.nan, -2.0, -3.0])
    assert gate.offer(currents, 0, False, 0) is None and gate.refused == 1
    held = gate.hold(0)
    np.testing.assert_array_equal(held.current_a, [1.0, 2.0, 0.0, 0.0, -2.0, 0.0])
    assert (held.command_stamp_ns, held.brake, held.reason) == (0, False, '')
    assert gate.offer(np.array([0.5, 1.5]), P, False, P) is None and gate.refused == 1


def test_a_brake_delay_of_one_second_counts_to_the_nanosecond() -> None:
    """Timed out (0 A) at once; the brake only once the command is timeout + 1 s + 1 ns old."""
    gate = active_gate(timeout_s=0.01, brake_delay_s=1.0)
    gate.offer(1.0, 0, False, 0)
    held = gate.hold(10 * P + 10**9)
    assert (held.current_a, held.brake, held.reason) == (0.0, False, 'command timeout')
    assert gate.hold(10 * P + 10**9 + 1).brake is True


def test_a_batch_without_a_safe_stop_releases_the_brake_as_one_value() -> None:
    """No element stopped: every run gets its command and the brake is off (False, as for one)."""
    gate = active_gate()
    gate.offer(np.array([1.0, -1.0]), 0, np.array([False, False]), 0)
    held = gate.hold(0)
    np.testing.assert_array_equal(held.current_a, [1.0, -1.0])
    assert held.brake is False and gate.brake is False and held.reason == ''


# -------------------------------------------------------------------------------- StampCheck
@pytest.mark.parametrize('sim', [False, True])
def test_stamps_from_0_to_the_largest_a_time_message_holds_are_valid(sim: bool) -> None:
    """0 and STAMP_MAX_NS are stamps; -1 ns and one beyond are INVALID, each counted."""
    check = StampCheck(P, sim=sim, future_tolerance_ns=10**19)
    assert check.check(-1, 0) is Verdict.INVALID and check.check(0, 0) is Verdict.OK
    fresh = StampCheck(P, sim=sim, future_tolerance_ns=10**19)
    assert fresh.check(limits.STAMP_MAX_NS + 1, 0) is Verdict.INVALID
    assert fresh.check(limits.STAMP_MAX_NS, 0) is Verdict.OK
    assert (check.invalid, fresh.invalid, check.last_ns) == (1, 1, 0)
    check.check(-5, 0)
    assert check.invalid == 2 and check.last_ns == 0  # refused: the grid stays


@pytest.mark.parametrize('sim', [False, True])
def test_the_callers_limit_is_inclusive_and_each_refusal_counted(sim: bool) -> None:
    """limit_ns itself is taken; a nanosecond beyond is FUTURE in either mode, counted each."""
    check = StampCheck(P, sim=sim, future_tolerance_ns=10**12)
    check.check(0, 0)
    assert check.check(2 * P, 0, limit_ns=P) is Verdict.FUTURE
    assert check.check(P + 1, 0, limit_ns=P) is Verdict.FUTURE
    assert check.refused_future == 2 and check.last_ns == 0
    assert check.check(P, 0, limit_ns=P) is Verdict.OK and check.last_ns == P


def test_on_a_one_nanosecond_grid_the_next_nanosecond_is_the_next_sample() -> None:
    """Period 1 ns: one ns ahead is OK (not old), the same stamp again is old."""
    check = StampCheck(1, sim=False, future_tolerance_ns=10**12)
    check.check(1000, 0)
    assert check.check(1001, 0) is Verdict.OK and check.check(1001, 0) is Verdict.OLD


def test_future_tolerance_is_inclusive_in_real_time() -> None:
    """A stamp exactly the tolerance ahead of the clock is taken; one nanosecond more is not."""
    check = StampCheck(P, sim=False, future_tolerance_ns=5 * P)
    assert check.check(5 * P + 1, 0) is Verdict.FUTURE and check.refused_future == 1
    assert check.check(5 * P, 0) is Verdict.OK and check.last_ns == 5 * P
    assert check.check(10**9, 0) is Verdict.FUTURE and check.refused_future == 2
    assert check.last_ns == 5 * P  # a refused stamp moves nothing


def test_real_time_duplicates_and_late_samples_are_each_counted() -> None:
    """The same stamp again and one a sample back are old, counted one by one; the grid stays."""
    check = StampCheck(P, sim=False, future_tolerance_ns=10**12)
    check.check(10 * P, 0)
    assert check.check(10 * P, 0) is Verdict.OLD and check.check(9 * P, 0) is Verdict.OLD
    assert (check.ignored_old, check.jumps, check.last_ns) == (2, 0, 10 * P)
    assert check.check(11 * P, 0) is Verdict.OK and check.last_ns == 11 * P


def test_jump_boundaries_in_real_time() -> None:
    """Ahead by jump_samples: missed samples; one more: a jump. Back as far: a jump; less: old."""
    check = StampCheck(P, sim=False, future_tolerance_ns=10**12, jump_samples=10)
    check.check(0, 0)
    assert check.check(10 * P, 0) is Verdict.OK
    assert check.check(21 * P, 0) is Verdict.JUMP and check.last_ns == 21 * P
    assert check.check(12 * P, 0) is Verdict.OLD  # 9 samples back: late, ignored
    assert check.check(11 * P, 0) is Verdict.JUMP  # 10 samples back: a restarted time base
    assert (check.jumps, check.ignored_old, check.last_ns) == (2, 1, 11 * P)


def test_default_jump_is_a_thousand_samples() -> None:
    """Without jump_samples: 1000 samples ahead are missed samples, 1001 a discontinuity."""
    assert JUMP_SAMPLES == 1000
    check = StampCheck(P, sim=False, future_tolerance_ns=10**13)
    check.check(0, 0)
    assert check.check(1000 * P, 0) is Verdict.OK
    assert check.check(2001 * P, 0) is Verdict.JUMP


def test_sim_duplicate_is_old_and_one_sample_back_a_restart() -> None:
    """Sim: the same stamp again is ignored; a stamp one sample back is a restarted plant."""
    check = StampCheck(P, sim=True, future_tolerance_ns=0)
    check.check(10 * P, 0)
    assert check.check(10 * P, 0) is Verdict.OLD and check.ignored_old == 1
    assert check.check(9 * P, 0) is Verdict.JUMP and check.last_ns == 9 * P
    assert check.check(10 * P, 0) is Verdict.OK
    assert check.check(11 * P + 1, 0) is Verdict.FUTURE  # a nanosecond beyond the next sample
    assert check.check(12 * P, 0) is Verdict.FUTURE and check.refused_future == 2
    assert check.last_ns == 10 * P


def test_reset_forgets_the_grid() -> None:
    """After reset any stamp starts a new grid without being counted as a jump."""
    check = StampCheck(P, sim=False, future_tolerance_ns=10**12)
    check.check(0, 0)
    check.reset()
    assert check.last_ns is None
    assert check.check(123, 0) is Verdict.OK and check.jumps == 0 and check.last_ns == 123
