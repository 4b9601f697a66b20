# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A loop that answers late: the delay estimate, the lowered feedback, sample by sample."""

from __future__ import annotations

import dataclasses

import pytest

from actuator_core import limits
from actuator_core.assembly import ControlSampleAssembly
from actuator_core.lateness import FLOOR_RISE_PER_SAMPLE, AnswerDelay
from actuator_controller.laws import CONTROLLER_NAMES, make_controller
from actuator_controller.reference import ReferenceSample, make_reference

P = 1_000_000  # 1 ms in ns
T0 = 1_700_000_000 * 10**9  # a wall-clock stamp
OFFSET = 123_456_789  # the receiver's monotonic clock against the joint's stamps [ns]


def test_the_delay_is_the_base_plus_the_periods_above_the_transit_floor():
    """On-time answers: the base; 2.6 ms above the fastest transit: base + 3; rounding at half."""
    d = AnswerDelay(P, base_delay_samples=1)
    assert d.update(T0, T0 + OFFSET + 300_000) == 1  # the first sets the floor
    assert d.update(T0 + P, T0 + P + OFFSET + 200_000) == 1  # faster: the floor falls to it
    assert d.update(T0 + 2 * P, T0 + 2 * P + OFFSET + 2_800_000) == 1 + 3
    assert d.update(T0 + 3 * P, T0 + 3 * P + OFFSET + 200_000 + P // 2 - 1_000) == 1
    assert d.update(T0 + 4 * P, T0 + 4 * P + OFFSET + 200_000 + P // 2 + 1_000) == 2
    assert AnswerDelay(P).update(T0, T0) == 0  # sim and offline: the stamp is the receipt


def test_the_floor_follows_a_slow_drift_and_starts_over_after_a_reset():
    """A transit rising 5 ppm never reads as late; after reset a new offset is the floor."""
    d = AnswerDelay(P, base_delay_samples=1)
    drift = 5e-6 * P  # < FLOOR_RISE_PER_SAMPLE periods per sample
    assert drift < FLOOR_RISE_PER_SAMPLE * P
    delays = {d.update(T0 + k * P, T0 + k * P + OFFSET + int(k * drift)) for k in range(200_000)}
    assert delays == {1}
    assert d.update(T0, T0 + OFFSET - 5 * P) == 1  # an earlier offset: the floor falls at once
    d.reset()
    assert d.update(T0, T0 + OFFSET + 50 * P) == 1  # a restarted joint: the new offset


@pytest.mark.parametrize('name', CONTROLLER_NAMES)
def test_the_feedback_scale_scales_the_feedback_gains_only_and_returns_to_the_given_ones(name):
    """Each law: FEEDBACK_GAINS times the scale, every other gain as given; 1 restores them."""
    law = make_controller(name)
    given = law.gains
    assert law.FEEDBACK_GAINS and all(hasattr(given, f) for f in law.FEEDBACK_GAINS)
    law.set_feedback_scale(0.25)
    for f in dataclasses.fields(given):
        value = getattr(given, f.name)
        expected = value * 0.25 if f.name in law.FEEDBACK_GAINS else value
        assert getattr(law.gains, f.name) == expected, f.name
    law.set_feedback_scale(1.0)
    assert law.gains is given


def test_a_lower_feedback_changes_the_feedback_and_not_the_feedforward():
    """PP-NFTSMC-ESO on the error: current changes; with e, z2, sigma zero, the same current."""
    ref = ReferenceSample(0.1, 0.5, 2.0)
    on_track = [make_controller('pp_nftsmc_eso') for _ in range(2)]
    off_track = [make_controller('pp_nftsmc_eso') for _ in range(2)]
    for pair in (on_track, off_track):
        pair[1].set_feedback_scale(0.15)
    same = [c.update(1.0, 0.1, 0.5, 3.0, ref).current_a for c in on_track]
    assert same[0] == pytest.approx(same[1], abs=1e-9)
    moved = [c.update(1.0, 0.12, 0.5, 3.0, ref).current_a for c in off_track]
    assert abs(moved[1] - same[1]) < 0.5 * abs(moved[0] - same[0])


def _assembly(base_delay_samples=1, **kwargs):
    law = make_controller('pp_nftsmc_eso')
    a = ControlSampleAssembly(
        law, make_reference('fast'), P, base_delay_samples=base_delay_samples, **kwargs
    )
    return a, law


def _sample(a, k, late_ns=0):
    """x_hat(k) then y(k), received ``late_ns`` after the fastest transit."""
    a.add_estimate(T0 + k * P, 0.0, 0.0, T0 + (k - 1) * P, 0.0, 0.0, initial=k == 0)
    return a.add_measurement(T0 + k * P, 0.0, T0 + k * P + OFFSET + late_ns)


def test_the_assembly_lowers_the_feedback_after_a_run_of_late_answers_and_restores_it():
    """Real time (base 1): 0.4 ms late is on time; 1.2 ms (delay 2) or more, 3 in a row: lowered.

    One late answer alone changes nothing; the first on-time answer restores the gains.
    """
    a, law = _assembly()
    given = law.gains
    assert limits.LATE_FEEDBACK_RUN_SAMPLES == 3
    lowered = limits.LATE_FEEDBACK_SCALE
    lateness_ms = (0, 0.4, 1.2, 0, 1.2, 3.0, 2.0, 4.0, 0.3, 1.5)
    scales = []
    for k, late_ms in enumerate(lateness_ms):
        assert _sample(a, k, int(late_ms * 1e6)) is not None
        scales.append(law.feedback_scale)
    assert scales == [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, lowered, lowered, 1.0, 1.0]
    assert law.gains is given and a.late_feedback == 2


def test_sim_and_offline_never_lower_the_feedback_and_one_turns_it_off():
    """Base 0 with receipts at the stamps: whole; late_feedback_scale 1: whole however late."""
    a, law = _assembly(base_delay_samples=0)
    for k in range(5):
        a.add_estimate(T0 + k * P, 0.0, 0.0, T0 + (k - 1) * P, 0.0, 0.0, initial=k == 0)
        a.add_measurement(T0 + k * P, 0.0)
        assert law.feedback_scale == 1.0
    a, law = _assembly(late_feedback_scale=1.0)
    for k, late_ms in enumerate((0, 5, 5, 5, 5)):
        _sample(a, k, late_ms * 1_000_000)
    assert law.feedback_scale == 1.0 and a.late_feedback == 2
