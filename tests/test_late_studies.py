# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Offline studies: late commands and late answers (actuator_sim.late_commands, late_answers)."""

from __future__ import annotations

import numpy as np
import pytest

from actuator_sim.late_answers import lag_profile, run_lagged
from actuator_sim.late_commands import late_mask, max_steady_error


@pytest.mark.slow
def test_late_commands_bursts_and_the_eso_integrating_the_commanded_current():
    """Late bursts have the asked length.

    The ESO integrating u(k) tolerates what integrating u(k-1) does not.
    """
    mask = late_mask(20000, 0.1, 3, seed=1)
    starts = np.flatnonzero(mask & ~np.roll(mask, 1))
    assert starts.size > 100 and 0.2 < mask.mean() < 0.3
    assert not late_mask(1000, 0.0, 3, seed=1).any()
    mask = late_mask(6000, 0.1, 3, seed=0)
    commanded = max_steady_error(mask, eso_integrates_applied=False, duration_s=6.0)
    held = max_steady_error(mask, eso_integrates_applied=True, duration_s=6.0)
    assert commanded < 3e-3 and held > 5 * commanded


def test_lag_bursts_have_the_asked_shape():
    """Lags in bursts: within the range, growing by at most one sample per sample, none at p=0."""
    lag = lag_profile(20000, 0.001, seed=3, lag_range=(2, 6), burst_range=(20, 40))
    assert 0.01 < (lag > 0).mean() < 0.2 and lag.max() == 6 and lag.min() == 0
    assert np.all(np.diff(lag) <= 1)  # the loop falls behind one sample at a time
    assert np.diff(lag).min() <= -2  # and catches up at once
    assert not lag_profile(1000, 0.0, seed=3).any()


@pytest.mark.slow
def test_a_joint_that_takes_late_answers_keeps_a_lagging_loop_off_the_limit():
    """The observer and controller 2-10 samples behind in bursts (actuator_sim.late_answers).

    The joint's default window (the command timeout's) keeps the error an order below a window of
    one sample, which holds older commands instead.
    """
    lag = lag_profile(6000, 0.0005, seed=0)
    assert (lag > 0).mean() > 0.1
    timeout_window, at_limit = run_lagged(lag, None, duration_s=6.0)
    one_sample, _ = run_lagged(lag, 1, duration_s=6.0)  # latched (inf) in this run
    undisturbed, none_at_limit = run_lagged(np.zeros(6000, dtype=int), None, duration_s=6.0)
    assert undisturbed < 1e-3 and none_at_limit == 0
    assert timeout_window < 2e-3 and at_limit > 0  # the bursts still swing, and it recovers
    assert one_sample > 10 * timeout_window
