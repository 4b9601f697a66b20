# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The observer's input pairing at its boundaries: patience, pending limits, repair, restart.

Each test pins one boundary of ``actuator_core.pairing`` (the sample a substitute is taken, the
farthest command kept, what a restart keeps), with the exact estimates the observer gives.
"""

from __future__ import annotations

import numpy as np
import pytest

from actuator_core.pairing import (
    MAX_STEPS_PER_CALL,
    PENDING_LIMIT,
    REALTIME_PATIENCE_SAMPLES,
    SIM_PATIENCE_SAMPLES,
    Estimate,
    ObserverInputPairing,
)
from actuator_eso.observer import EsoGains, ExtendedStateObserver, eso_step

P = 1_000_000  # 1 ms in ns
DT = 1e-3


def pairing(patience: int = REALTIME_PATIENCE_SAMPLES):
    """Return a pairing over a fresh observer of Table 4's gains, and the observer."""
    eso = ExtendedStateObserver(EsoGains(), DT)
    return ObserverInputPairing(eso, P, eso.correction, patience), eso


def test_the_documented_constants() -> None:
    """16 steps per message, 256 pending samples, patience 1 sample (real time) or 100 (sim)."""
    assert (MAX_STEPS_PER_CALL, PENDING_LIMIT) == (16, 256)
    assert (REALTIME_PATIENCE_SAMPLES, SIM_PATIENCE_SAMPLES) == (1, 100)


def test_patience_waits_exactly_its_samples_for_a_missing_command() -> None:
    """Patience 3: y(1), y(2), y(3) wait for u(1); y(4) steps sample 1 with the last current."""
    pair, _ = pairing(patience=3)
    pair.add_measurement(0, 0.0)
    pair.add_command(0, 1.5)
    assert pair.add_measurement(P, 0.0) == []
    assert pair.add_measurement(2 * P, 0.0) == [] and pair.add_measurement(3 * P, 0.0) == []
    out = pair.add_measurement(4 * P, 0.0)
    assert [e.sample_ns for e in out] == [2 * P] and out[0].substituted
    assert out[0].input_current_a == 1.5 and pair.substituted == 1 and pair.steps == 2


def test_a_missing_measurement_is_replaced_by_the_estimate_itself() -> None:
    """u(1) in, y(1) lost, y(2) in: sample 1 integrates y = x1_hat (no correction) and u(1)."""
    pair, eso = pairing()
    pair.add_measurement(0, 0.1)
    pair.add_command(0, 2.0)
    x1_before = eso.state[0]
    pair.add_command(P, 3.0)
    out = pair.add_measurement(2 * P, 0.1)
    assert out[0].input_position_rad == x1_before and out[0].input_current_a == 3.0
    assert not out[0].substituted


def test_late_command_repairs_each_substituted_sample_exactly() -> None:
    """u(1) arrives two samples late: the state equals the run where it came in time."""
    pair, eso = pairing()
    pair.add_measurement(0, 0.0)
    pair.add_command(0, 1.0)
    pair.add_measurement(P, 0.01)
    pair.add_measurement(2 * P, 0.02)  # sample 1 stepped with u = 1.0
    pair.add_command(2 * P, 0.5)
    pair.add_measurement(3 * P, 0.03)  # sample 2 stepped with its own u
    pair.add_command(P, 4.0)  # late u(1): two steps since
    assert pair.repaired == 1 and pair.last_current == 0.5
    x = (0.0, 0.0, 0.0)
    for y, u in ((0.0, 1.0), (0.01, 4.0), (0.02, 0.5)):
        x = eso_step(*x, y, u, DT, EsoGains())
    assert eso.state == pytest.approx(x, rel=1e-12, abs=1e-12)
    pair.add_command(P, 9.0)  # a second copy of it repairs nothing
    assert pair.repaired == 1


def test_a_repair_of_the_last_sample_also_corrects_the_next_substitute() -> None:
    """u(1) late by one sample: repaired at once, and u(1) is the current a later gap uses."""
    pair, _ = pairing()
    pair.add_measurement(0, 0.0)
    pair.add_command(0, 1.0)
    pair.add_measurement(P, 0.0)
    pair.add_measurement(2 * P, 0.0)  # sample 1 stepped with the substitute 1.0
    pair.add_command(P, 5.0)
    assert (pair.repaired, pair.last_current) == (1, 5.0)
    out = pair.add_measurement(3 * P, 0.0)  # u(2) never came: substituted with u(1)
    assert out[0].substituted and out[0].input_current_a == 5.0
    pair.add_command(2 * P, 6.0)
    assert pair.repaired == 2


def test_a_command_for_an_unsubstituted_past_sample_changes_nothing() -> None:
    """A duplicate of a command already integrated is dropped without touching the state."""
    pair, eso = pairing()
    pair.add_measurement(0, 0.0)
    pair.add_command(0, 1.0)
    before = eso.state
    assert pair.add_command(0, 7.0) == [] and eso.state == before and pair.repaired == 0


def test_commands_beyond_the_next_sample_are_refused_and_a_duplicate_is_ignored() -> None:
    """A command for the next sample is kept; one sample beyond it is refused with the reason."""
    pair, _ = pairing()
    pair.add_measurement(0, 0.0)
    pair.add_command(2 * P, 1.0)
    assert pair.refused == 1 and 2 * P not in pair.currents
    assert pair.refusal.endswith('2 ms ahead of the newest measurement received')
    pair.add_command(P // 2, 1.0)
    assert pair.refused == 2 and pair.refusal.endswith('off the sample grid')
    pair.add_measurement(P, 0.0)
    pair.add_command(2 * P, 1.0)  # the next sample: kept
    assert pair.refused == 2 and pair.currents.get(2 * P) == 1.0
    pair.add_command(2 * P, 1.0)  # the same command again
    assert pair.ignored == 1 and pair.currents[2 * P] == 1.0


def test_commands_before_the_first_measurement_keep_only_the_newest() -> None:
    """More than PENDING_LIMIT early commands: the oldest go; a restart keeps those not older."""
    pair, _ = pairing()
    for k in range(PENDING_LIMIT + 5):
        pair.add_command(k * P, float(k))
    assert len(pair.currents) == PENDING_LIMIT and min(pair.currents) == 5 * P
    out = pair.add_measurement(10 * P, 0.0)
    assert out[0].initial and out[1].input_current_a == 10.0
    assert min(pair.currents) > 10 * P


def test_restart_counts_only_restarts_and_forgets_the_old_samples() -> None:
    """The first start is no restart; a restart drops measurements and substitutes before it."""
    pair, eso = pairing(patience=1000)
    pair.add_measurement(0, 0.0)
    assert pair.restarts == 0
    pair.add_measurement(5 * P, 0.3)
    pair.add_command(3 * P, 1.0)
    out = pair.restart(100 * P, 0.5)
    assert pair.restarts == 1 and eso.state == (0.5, 0.0, 0.0) and pair.last_current == 0.0
    assert out == [out[0]] and out[0].initial and out[0].input_ns == 0
    assert list(pair.measurements) == [100 * P] and not pair.substitutes
    assert 3 * P not in pair.currents and pair.newest_measurement_ns == 100 * P


def test_each_message_steps_at_most_the_bound_and_the_rest_follow() -> None:
    """40 pairs freed at once: 16, then 16, then 8 steps over the following messages."""
    pair, _ = pairing(patience=1000)
    pair.add_measurement(0, 0.0)
    for k in range(1, 41):
        pair.add_measurement(k * P, 0.0)
        pair.add_command(k * P, 0.0)
    first = pair.add_command(0, 0.0)
    assert len(first) == MAX_STEPS_PER_CALL
    second = pair.add_measurement(41 * P, 0.0)
    third = pair.add_measurement(42 * P, 0.0)
    assert len(second) == MAX_STEPS_PER_CALL and len(third) == 41 - 2 * MAX_STEPS_PER_CALL
    assert third[-1].sample_ns == 41 * P


def test_a_batch_command_repeated_is_ignored_and_one_differing_in_one_run_conflicts() -> None:
    """Arrays (a batch of runs): the same command twice is one; a difference in any run is two.

    The conflicted sample is left to the substitute, for every run of the batch.
    """
    eso = ExtendedStateObserver(EsoGains(), DT, x_hat0=(np.zeros(2),) * 3)
    pair = ObserverInputPairing(eso, P, eso.correction)
    pair.add_measurement(0, np.zeros(2))
    pair.add_command(P, np.array([1.0, 2.0]))  # the next sample: kept
    assert pair.add_command(P, np.array([1.0, 2.0])) == []
    assert (pair.ignored, pair.conflicts) == (1, 0) and list(pair.currents[P]) == [1.0, 2.0]
    pair.add_command(P, np.array([1.0, 3.0]))
    assert pair.conflicts == 1 and P in pair.conflicted and P not in pair.currents
    assert pair.refusal == (
        f'two different commands for sample {P} ns (a second publisher?): neither used, the '
        'sample is integrated with the last current'
    )


@pytest.mark.parametrize('gap, restarts', [(4, 0), (5, 1)])
def test_a_measurement_the_restart_gap_ahead_of_x_hat_restarts_the_observer(gap, restarts):
    """restart_gap_samples 5: y 5 samples ahead of x_hat restarts there; 4 steps up to it."""
    eso = ExtendedStateObserver(EsoGains(), DT)
    pair = ObserverInputPairing(eso, P, eso.correction, restart_gap_samples=5)
    pair.add_measurement(0, 0.0)
    pair.add_command(0, 1.0)  # x_hat now at sample 1
    out = pair.add_measurement((1 + gap) * P, 0.3)
    assert (pair.gap_restarts, pair.restarts) == (restarts, restarts)
    if restarts:
        assert [e.sample_ns for e in out] == [6 * P] and out[0].initial
        assert eso.state == (0.3, 0.0, 0.0)
    else:  # samples 1..4 stepped with substitutes: x_hat reaches y(5)
        assert [e.sample_ns for e in out] == [2 * P, 3 * P, 4 * P, 5 * P]
        assert all(e.substituted for e in out) and pair.restarts == 0
    pair.add_command(pair.sample_ns, 0.0)
    pair.add_measurement(pair.sample_ns + 5 * P, 0.4)  # the next gap: counted again
    assert pair.gap_restarts == restarts + 1


def test_refusal_says_nothing_until_a_command_is_refused_and_clears_on_the_next() -> None:
    """'' when nothing was refused; the reason (ms ahead, to 6 digits); '' again after."""
    pair, _ = pairing()
    assert pair.refusal == ''
    pair.add_measurement(0, 0.0)
    pair.add_command(100 * P, 1.0)
    assert pair.refusal == (
        f'command stamped {100 * P} ns refused: 100 ms ahead of the newest measurement received'
    )
    pair.add_command(0, 1.0)
    assert pair.refusal == '' and pair.refused == 1


def test_every_conflicted_sample_is_counted() -> None:
    """Two samples each claimed by two different commands (x_hat waits at 0): two conflicts."""
    pair, _ = pairing(patience=10)
    pair.add_measurement(0, 0.0)
    pair.add_measurement(P, 0.0)
    for stamp in (P, 2 * P):
        pair.add_command(stamp, 1.0)
        pair.add_command(stamp, 2.0)
    assert pair.conflicts == 2 and pair.conflicted == {P, 2 * P}


def test_the_start_estimate_is_x_hat_0_and_integrated_nothing() -> None:
    """x_hat(0) = (y, 0, 0): no input stamp, position or current, initial, not substituted."""
    pair, _ = pairing()
    out = pair.add_measurement(7 * P, 0.25)
    assert out == [Estimate(7 * P, (0.25, 0.0, 0.0), 0, 0.0, 0.0, True, False)]


def test_each_step_names_the_pair_it_integrated_and_every_substitute_is_counted() -> None:
    """Estimate k+1 says it integrated sample k; two samples without a command: two substitutes."""
    pair, _ = pairing()
    pair.add_measurement(0, 0.0)
    (step,) = pair.add_command(0, 1.0)
    assert (step.sample_ns, step.input_ns, step.input_current_a) == (P, 0, 1.0)
    pair.add_measurement(P, 0.01)
    pair.add_measurement(2 * P, 0.02)  # u(1) did not come: substituted
    out = pair.add_measurement(3 * P, 0.03)  # nor u(2)
    assert [(e.sample_ns, e.input_ns, e.substituted) for e in out] == [(3 * P, 2 * P, True)]
    assert pair.substituted == 2


def test_every_duplicate_command_and_every_restart_is_counted() -> None:
    """The same command three times: two ignored. Two restarts after the start: two."""
    pair, _ = pairing(patience=10)
    pair.add_measurement(0, 0.0)
    for _ in range(3):
        pair.add_command(P, 1.0)
    assert pair.ignored == 2
    pair.restart(10 * P, 0.0)
    pair.restart(20 * P, 0.0)
    assert pair.restarts == 2


def test_measurements_waiting_for_their_commands_keep_the_newest_pending_limit() -> None:
    """300 measurements and no command (patience unbounded): the newest PENDING_LIMIT stay."""
    pair, _ = pairing(patience=10**6)
    for k in range(301):
        pair.add_measurement(k * P, 0.0)
    assert len(pair.measurements) == PENDING_LIMIT
    assert min(pair.measurements) == (301 - PENDING_LIMIT) * P


def test_a_conflicted_sample_stays_conflicted_while_x_hat_waits_at_it() -> None:
    """Two commands for sample 1 while x_hat waits there: a third is ignored, 1 is substituted."""
    pair, _ = pairing()
    pair.add_measurement(0, 0.0)
    pair.add_command(0, 1.0)  # x_hat at sample 1
    pair.add_command(P, 2.0)
    pair.add_command(P, 3.0)  # conflict
    assert pair.add_measurement(P, 0.0) == []  # waits for u(1), which is conflicted
    assert pair.add_command(P, 4.0) == []  # still conflicted: not used
    out = pair.add_measurement(2 * P, 0.0)
    assert [(e.input_ns, e.substituted, e.input_current_a) for e in out] == [(P, True, 1.0)]
