# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Boundaries of the core's small modules: xmath, stats, timing, limits, clock, sample_log, etc.

The modules: xmath, stats, timing, limits, clock, sample_log and decimation (params: test_params).

Each test kills mutants that survived ``make mutation`` (docs/mutation-report.md) or that no
test of the selection reached: a scalar sent down numpy's path (a numpy scalar where ``math``
gives a float), a strict inequality made loose, an accumulation made an assignment, a chunk
index off by one. The expected figures follow from the docstrings' definitions, by hand.
"""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from actuator_core import clock as clock_module
from actuator_core import limits
from actuator_core import xmath as xm
from actuator_core.clock import Clock, Schedule, SteppedClock
from actuator_core.decimation import Decimator
from actuator_core.limits import input_current_gain_limit
from actuator_core.sample_log import CHUNK_ROWS, SampleLog
from actuator_core.stats import missed_samples, percentiles
from actuator_core.timing import period_ns, sample_time_s, stamp_to_ns

# --- xmath ------------------------------------------------------------------------------------

ELEMENTARY = [
    (xm.exp, math.exp, 0.5),
    (xm.log, math.log, 2.5),
    (xm.sin, math.sin, 0.5),
    (xm.cos, math.cos, 0.5),
    (xm.tanh, math.tanh, 0.5),
]


@pytest.mark.parametrize('f, reference, x', ELEMENTARY)
def test_an_elementary_function_of_a_scalar_is_maths_float(f, reference, x):
    """A scalar takes math's path: a builtin float equal to math's, not a numpy scalar."""
    y = f(x)
    assert type(y) is float
    assert y == reference(x)


@pytest.mark.parametrize('f, reference, x', ELEMENTARY)
def test_an_elementary_function_of_an_array_is_elementwise(f, reference, x):
    """An array takes numpy's path: one value per element (math refuses a 2-element array)."""
    y = f(np.array([x, 2.0 * x]))
    assert isinstance(y, np.ndarray) and y.shape == (2,)
    assert y == pytest.approx([reference(x), reference(2.0 * x)], rel=1e-15)


@pytest.mark.parametrize('x, s', [(2.5, 1.0), (0.5, 1.0), (-0.5, -1.0), (-3.0, -1.0), (0.0, 0.0)])
def test_sign_of_a_scalar(x, s):
    """-1, 0 or 1 with sign(0) = 0; 0.5 and -0.5 tell the comparisons with 0 from those with 1."""
    result = xm.sign(x)
    assert result == s and type(result) is float


def test_sign_of_an_array():
    """Elementwise, sign(0) = 0 there too."""
    assert np.array_equal(xm.sign(np.array([-2.0, 0.0, 0.25])), [-1.0, 0.0, 1.0])


def test_fabs_of_a_scalar_and_of_an_array():
    """A scalar's absolute value is a builtin float; an array's is elementwise."""
    assert xm.fabs(-2.5) == 2.5 and type(xm.fabs(-2.5)) is float
    assert np.array_equal(xm.fabs(np.array([-1.5, 2.0])), [1.5, 2.0])


def test_isfinite_of_a_scalar_is_a_bool():
    """A scalar answers a builtin bool (True / False themselves), not numpy's bool."""
    assert xm.isfinite(1.0) is True
    assert xm.isfinite(math.inf) is False and xm.isfinite(math.nan) is False


def test_isfinite_of_an_array_is_elementwise():
    """NaN and both infinities are not finite; a finite element is."""
    result = xm.isfinite(np.array([1.0, math.nan, -math.inf, math.inf]))
    assert np.array_equal(result, [True, False, False, False])


def test_where_of_scalars_picks_one():
    """Scalars: a where the condition holds, else b."""
    assert xm.where(True, 1.0, 2.0) == 1.0
    assert xm.where(False, 1.0, 2.0) == 2.0


def test_where_of_an_array_condition_with_scalar_branches():
    """An array condition alone makes the answer elementwise."""
    result = xm.where(np.array([True, False]), 1.0, 2.0)
    assert np.array_equal(result, [1.0, 2.0])


@pytest.mark.parametrize('condition', [True, False])
def test_where_of_a_scalar_condition_with_one_array_branch(condition):
    """An array in either branch makes the answer an array of its shape, the scalar broadcast."""
    a = np.array([1.0, 2.0])
    b = np.array([7.0, 8.0])
    assert np.array_equal(xm.where(condition, a, 5.0), a if condition else [5.0, 5.0])
    assert np.array_equal(xm.where(condition, 5.0, b), [5.0, 5.0] if condition else b)


def test_where_of_arrays_everywhere():
    """Condition and both branches arrays: elementwise choice."""
    result = xm.where(np.array([True, False, True]), np.array([1.0, 2, 3]), np.array([4.0, 5, 6]))
    assert np.array_equal(result, [1.0, 5.0, 3.0])


@pytest.mark.parametrize('x, clipped', [(-3.0, -1.0), (0.5, 0.5), (4.0, 2.0)])
def test_clip_of_a_scalar(x, clipped):
    """Below low: low; within: x; above high: high."""
    assert xm.clip(x, -1.0, 2.0) == clipped


def test_clip_of_an_array():
    """Elementwise, both bounds at once."""
    assert np.array_equal(xm.clip(np.array([-3.0, 0.5, 4.0]), -1.0, 2.0), [-1.0, 0.5, 2.0])


def test_all_true_and_any_true_of_scalars():
    """A bool is its own answer, True or False."""
    assert xm.all_true(True) is True and xm.all_true(False) is False
    assert xm.any_true(True) is True and xm.any_true(False) is False


def test_all_true_and_any_true_of_arrays():
    """All: every element true; any: at least one (a mixed array tells them apart)."""
    assert xm.all_true(np.array([True, True])) is True
    assert xm.all_true(np.array([True, False])) is False
    assert xm.any_true(np.array([False, True])) is True
    assert xm.any_true(np.array([False, False])) is False


def test_logical_not():
    """A bool's negation is a builtin bool; an array's is elementwise."""
    assert xm.logical_not(True) is False and xm.logical_not(False) is True
    assert np.array_equal(xm.logical_not(np.array([True, False])), [False, True])


# --- stats ------------------------------------------------------------------------------------


def test_percentiles_of_an_evenly_spaced_set():
    """0, 2, ..., 200 (101 values, shuffled): the p-th percentile is 2p, max 200, mean 100."""
    values = np.random.default_rng(3).permutation(np.arange(101) * 2.0)
    assert percentiles(values, 'lat', mean=True) == {
        'lat_p50': 100.0,
        'lat_p99': 198.0,
        'lat_max': 200.0,
        'lat_mean': pytest.approx(100.0, rel=1e-15),
    }


def test_percentiles_leave_the_mean_out_unless_asked():
    """The default has no mean: exactly the three keys p50, p99 and max."""
    assert percentiles([1.0, 3.0, 2.0], 'x') == {
        'x_p50': 2.0,
        'x_p99': pytest.approx(2.98, rel=1e-14),  # rank 1.98: 2 + 0.98 (3 - 2)
        'x_max': 3.0,
    }


def test_percentiles_of_one_value():
    """One value is a summary (only an empty array gives None): every figure is that value."""
    assert percentiles([4.5], 'x', mean=True) == {
        'x_p50': 4.5,
        'x_p99': 4.5,
        'x_max': 4.5,
        'x_mean': 4.5,
    }


@pytest.mark.parametrize(
    'mean, keys',
    [(False, ['y_p50', 'y_p99', 'y_max']), (True, ['y_p50', 'y_p99', 'y_max', 'y_mean'])],
)
def test_percentiles_of_nothing_are_none(mean, keys):
    """An empty array: the same keys, each None."""
    assert percentiles([], 'y', mean=mean) == dict.fromkeys(keys)


def test_percentiles_of_single_precision_values_in_double():
    """float32 values are summarised in double precision (float32 arithmetic rounds at ~6e-8)."""
    v = np.array([0.1, 0.2, 0.7], dtype=np.float32)
    d = [float(x) for x in v]  # the exact double values of the float32 samples
    out = percentiles(v, 'z', mean=True)
    assert out['z_mean'] == pytest.approx(sum(d) / 3.0, rel=1e-14)
    # p99 of 3 values: rank 0.99 * (3 - 1) = 1.98, linear between the 2nd and 3rd smallest
    assert out['z_p99'] == pytest.approx(d[1] + 0.98 * (d[2] - d[1]), rel=1e-14)
    assert out['z_p50'] == d[1] and out['z_max'] == d[2]


P = 1_000_000  # 1 ms in ns


def test_missed_samples_sum_the_gaps():
    """Gaps of 1, 2, 1, 4 and 3 periods: 0 + 1 + 0 + 3 + 2 = 6 samples never answered."""
    stamps = np.array([0, 1, 3, 4, 8, 11]) * P + 5 * P
    assert missed_samples(stamps, P) == 6
    assert missed_samples(list(stamps), P) == 6


def test_one_gap_of_two_periods_misses_one_sample():
    """The smallest gap that misses a sample: two periods, one sample between."""
    assert missed_samples([7 * P, 9 * P], P) == 1


def test_too_few_stamps_miss_nothing():
    """No gap (one stamp or none): nothing missed."""
    assert missed_samples([3 * P], P) == 0
    assert missed_samples(np.array([], dtype=np.int64), P) == 0


def test_a_gap_counts_whole_periods():
    """Stamps 1.5 periods apart (jitter, none missing): a gap under two periods misses none."""
    assert missed_samples([0, 3 * P // 2, 3 * P, 9 * P // 2], P) == 0


def test_a_step_back_of_unsigned_stamps_misses_nothing():
    """Stamps as unsigned integers that step back: a negative gap, not one wrapped to 2**64."""
    stamps = np.array([5, 6, 2, 3], dtype=np.uint64) * np.uint64(P)
    assert missed_samples(stamps, P) == 0


# --- timing -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    'dt_s, ns',
    [(1.0e-3, 1_000_000), (1.0, 1_000_000_000), (7.0, 7_000_000_000), (2.5e-4, 250_000)],
)
def test_period_ns(dt_s, ns):
    """Seconds times 1e9, rounded to the nearest nanosecond (1 ms is 10**6 ns exactly)."""
    assert period_ns(dt_s) == ns and type(period_ns(dt_s)) is int


def test_sample_time_s():
    """Nanoseconds times 1e-9: 1 s, 2.5 ms."""
    assert sample_time_s(1_000_000_000) == pytest.approx(1.0, rel=1e-15)
    assert sample_time_s(2_500_000) == pytest.approx(2.5e-3, rel=1e-15)


def test_stamp_to_ns():
    """Return sec * 10**9 + nanosec, of any object with the two fields."""
    assert stamp_to_ns(SimpleNamespace(sec=3, nanosec=250)) == 3_000_000_250
    assert stamp_to_ns(SimpleNamespace(sec=1_700_000_000, nanosec=999_999_999)) == (
        1_700_000_000_999_999_999
    )


# --- limits -----------------------------------------------------------------------------------


def test_input_current_gain_limit():
    """2 theta_1n dt with theta_1n = k_tn / (J_n N) of Table 1: 0.0629 rad/s/A at 1 ms."""
    theta1n = 0.105 / (3.34e-5 * 100.0)
    assert input_current_gain_limit(1.0e-3) == pytest.approx(2.0 * theta1n * 1.0e-3, rel=1e-12)
    assert input_current_gain_limit(4.0e-3) == pytest.approx(2.0 * theta1n * 4.0e-3, rel=1e-12)


# --- clock ------------------------------------------------------------------------------------


class _FixedClock(Clock):
    """The system clock's sleep_until with a monotonic clock that reads a fixed time."""

    def __init__(self, now_ns):
        self._now = now_ns

    def now_ns(self) -> int:
        return self._now


@pytest.fixture
def sleeps(monkeypatch):
    """Record the durations time.sleep is asked for (nothing sleeps)."""
    asked = []
    monkeypatch.setattr(clock_module.time, 'sleep', asked.append)
    return asked


def test_clock_sleeps_the_remaining_time(sleeps):
    """Deadline 2.5 ms ahead: one sleep of 2.5e-3 s; 1 ns ahead: one of 1e-9 s."""
    _FixedClock(10 * P).sleep_until(10 * P + 2_500_000)
    _FixedClock(10 * P).sleep_until(10 * P + 1)
    assert sleeps == [pytest.approx(2.5e-3, rel=1e-12), pytest.approx(1.0e-9, rel=1e-12)]


def test_clock_does_not_sleep_at_or_past_the_deadline(sleeps):
    """The clock reads the deadline, or a later time: no sleep at all."""
    _FixedClock(10 * P).sleep_until(10 * P)
    _FixedClock(10 * P).sleep_until(4 * P)
    assert sleeps == []


def test_stepped_clock_advance_moves_both_clocks():
    """Wall = monotonic + offset; advance adds to the monotonic time (twice: the sum)."""
    c = SteppedClock(monotonic_ns=5_000, wall_offset_ns=70_000)
    assert (c.now_ns(), c.wall_ns()) == (5_000, 75_000)
    c.advance(300)
    c.advance(200)
    assert (c.now_ns(), c.wall_ns()) == (5_500, 75_500)


def test_stepped_clock_step_wall_moves_the_wall_clock_only():
    """A wall step adds to the offset, backwards too; the monotonic clock stays."""
    c = SteppedClock(monotonic_ns=5_000, wall_offset_ns=70_000)
    c.step_wall(1_000)
    c.step_wall(-4_000)
    assert (c.now_ns(), c.wall_ns()) == (5_000, 72_000)


def test_stepped_clock_sleep_until_never_goes_back():
    """A deadline ahead is reached at once; one behind leaves the time where it is."""
    c = SteppedClock(monotonic_ns=5_000, wall_offset_ns=0)
    c.sleep_until(8_000)
    assert c.now_ns() == 8_000
    c.sleep_until(6_000)
    assert c.now_ns() == 8_000


def test_schedule_on_time():
    """Called before each deadline: the grid start + k period, nothing skipped."""
    s = Schedule(period_ns=P, start_ns=3 * P)
    assert s.skipped == 0
    assert s.next(3 * P + 10) == (4 * P, 0)
    assert s.next(4 * P - 1) == (5 * P, 0)
    assert s.skipped == 0


def test_schedule_at_the_deadline_itself():
    """The next deadline is after now: at now = deadline that one is skipped."""
    s = Schedule(period_ns=P, start_ns=3 * P)
    assert s.next(4 * P) == (5 * P, 1)


def test_schedule_after_a_stall():
    """A call 2.5 periods past the next deadline: 3 skipped, the next on the grid after now."""
    s = Schedule(period_ns=P, start_ns=3 * P)
    assert s.next(4 * P + 5 * P // 2) == (7 * P, 3)
    assert s.skipped == 3


def test_schedule_counts_the_skipped_over_stalls():
    """Two stalls, 3 then 2 deadlines skipped: the total is 5."""
    s = Schedule(period_ns=P, start_ns=0)
    assert s.next(3 * P + 1) == (4 * P, 3)
    assert s.next(6 * P + 1) == (7 * P, 2)
    assert s.skipped == 5


# --- sample_log -------------------------------------------------------------------------------


def test_sample_log_default_cap_is_one_hour_at_one_kilohertz():
    """max_rows defaults to 3600 s * 1000 samples/s; a fresh log has no rows, none dropped."""
    log = SampleLog(['a', 'b'])
    assert log.max_rows == 3_600_000 and log.columns == ('a', 'b')
    assert (log.rows, log.dropped) == (0, 0)


def test_sample_log_keeps_exactly_max_rows():
    """Rows up to max_rows are kept, each further one counted once as dropped."""
    log = SampleLog(('a',), max_rows=3)
    for i in range(5):
        log.append((i,))
    assert (log.rows, log.dropped) == (3, 2)
    assert np.array_equal(log.array(), [[0], [1], [2]])


def test_sample_log_keeps_int64_exactly():
    """int64 rows, also beyond double precision (2**62 + 1 is no double)."""
    log = SampleLog(('a', 'b'))
    log.append((2**62 + 1, -7))
    log.append((3, 2**53 + 1))
    data = log.array()
    assert data.dtype == np.int64
    assert data.tolist() == [[2**62 + 1, -7], [3, 2**53 + 1]]


def test_an_empty_sample_log_is_an_int64_array_of_no_rows():
    """No rows: shape (0, columns), int64, from array() and since()."""
    log = SampleLog(('a', 'b', 'c'))
    for empty in (log.array(), log.since(0)):
        assert empty.shape == (0, 3) and empty.dtype == np.int64


def _log_of(rows: int) -> SampleLog:
    """Return a log of ``rows`` rows (i, -i)."""
    log = SampleLog(('i', 'neg'))
    for i in range(rows):
        log.append((i, -i))
    return log


ROWS = 3 * CHUNK_ROWS + 10  # four chunks, the last partly filled


def test_sample_log_array_joins_every_chunk():
    """Four chunks, the last partly filled: every row once, in order."""
    for rows in (1, CHUNK_ROWS, CHUNK_ROWS + 1, 2 * CHUNK_ROWS + 3, ROWS):
        data = _log_of(rows).array()
        assert data.shape == (rows, 2)
        assert np.array_equal(data[:, 0], np.arange(rows))
        assert np.array_equal(data[:, 1], -np.arange(rows))


@pytest.mark.parametrize(
    'start',
    [-5, 0, 1, 17, CHUNK_ROWS - 1, CHUNK_ROWS, CHUNK_ROWS + 7, 2 * CHUNK_ROWS + 1, ROWS - 1],
)
def test_sample_log_since(start):
    """Rows start onwards (a negative start: all), across chunk boundaries."""
    log = _log_of(ROWS)
    data = log.since(start)
    first = max(start, 0)
    assert np.array_equal(data[:, 0], np.arange(first, ROWS))
    assert np.array_equal(data[:, 1], -np.arange(first, ROWS))


@pytest.mark.parametrize('start', [ROWS, 4 * CHUNK_ROWS, 4 * CHUNK_ROWS + 3, 10 * CHUNK_ROWS])
def test_sample_log_since_the_end_is_empty(start):
    """From the row count on there are no rows, also from a chunk that does not exist yet."""
    data = _log_of(ROWS).since(start)
    assert data.shape == (0, 2) and data.dtype == np.int64


def test_sample_log_since_of_two_chunks():
    """Two chunks (the first full): rows from the second chunk's count on are none."""
    log = _log_of(CHUNK_ROWS + 10)
    assert log.since(2 * CHUNK_ROWS).shape == (0, 2)
    assert np.array_equal(
        log.since(CHUNK_ROWS + 4)[:, 0], np.arange(CHUNK_ROWS + 4, CHUNK_ROWS + 10)
    )


def test_sample_log_save(tmp_path):
    """One array per column, named after it."""
    log = _log_of(5)
    log.save(str(tmp_path / 'log.npz'))
    with np.load(tmp_path / 'log.npz') as saved:
        assert sorted(saved.files) == ['i', 'neg']
        assert np.array_equal(saved['i'], np.arange(5))
        assert np.array_equal(saved['neg'], -np.arange(5))


# --- decimation --------------------------------------------------------------------------------


def test_decimator_passes_the_rate_on_a_grid_and_restarts_after_a_gap():
    d = Decimator(100.0)
    arrivals = np.arange(0, 2_000_000_000, 1_000_000) + 37_000  # 1 kHz for 2 s
    passed = [t for t in arrivals.tolist() if d.admit(t)]
    assert len(passed) == 200  # every tenth, none bunched
    assert set(np.diff(passed).tolist()) == {10_000_000}
    assert (d.admitted, d.skipped) == (200, 1800)
    # A gap of 5 s (the loop stopped): the next message passes at once, the grid restarts there.
    assert d.admit(7_000_037_000) and not d.admit(7_001_037_000)
    assert not d.admit(7_010_036_999) and d.admit(7_010_037_000)  # the grid point itself passes


def test_decimator_on_a_late_grid_point_keeps_the_grid():
    d = Decimator(100.0)  # 10 ms
    assert d.admit(0) and d.admit(13_000_000)  # 3 ms late: the next point is still 20 ms
    assert not d.admit(19_999_999) and d.admit(20_000_000)
    assert d.admit(40_000_000)  # exactly one period late: restarts at 50 ms, not 30 ms
    assert not d.admit(49_999_999) and d.admit(50_000_000)


def test_a_clock_that_steps_back_restarts_the_grid():
    d = Decimator(100.0)
    assert d.admit(5_000_000_000) and not d.admit(5_001_000_000)
    # The grid's last point is 5.000 s; one before it (a restarted sim clock) restarts there.
    assert d.admit(4_999_999_999) and not d.admit(5_000_000_000)
    assert d.admit(5_009_999_999)


def test_a_forced_message_passes_off_the_grid_without_moving_it():
    d = Decimator(100.0)
    assert d.admit(0)
    assert d.admit(3_000_000, force=True)  # a status change at 3 ms
    assert not d.admit(9_000_000)  # the grid is still 0, 10, 20 ms
    assert d.admit(10_000_000)
    assert d.admitted == 3 and d.skipped == 1
    first = Decimator(100.0)  # a forced first message starts the grid as any first one does
    assert first.admit(5_000_000, force=True) and not first.admit(6_000_000)
    assert first.admit(15_000_000)


def test_decimator_at_rate_0_passes_everything_and_refuses_a_negative_or_nan_rate():
    d = Decimator(0.0)
    assert all(d.admit(t) for t in range(0, 1000, 1)) and d.admitted == 1000
    assert d.skipped == 0
    assert Decimator(1.0e3).period_ns == 1_000_000 and Decimator(3.0).period_ns == 333_333_333
    assert Decimator(0.5).period_ns == 2_000_000_000  # below 1 Hz is a rate too
    assert Decimator(0.0).period_ns == 0 and d.admit(999) and d.admit(999)  # repeats pass too


def test_a_repeated_stamp_is_admitted_once():
    for rate_hz, grid_ns in ((100.0, 10_000_000), (1.0e9, 1)):
        d = Decimator(rate_hz)
        assert d.period_ns == grid_ns
        assert d.admit(0) and not d.admit(0), rate_hz  # the grid point itself, again
        assert d.admit(grid_ns) and not d.admit(grid_ns)
    for bad in (-1.0, -1e-9, math.nan):
        with pytest.raises(ValueError, match='rate_hz must be >= 0'):
            Decimator(bad)


def test_values_are_judged_against_their_physical_bound_in_one_place():
    """actuator_core.values: finite and within +-bound (inclusive), the refusal's exact words."""
    from actuator_core import values

    assert values.within(2.0, 2.0) and values.within(-2.0, 2.0)
    assert not values.within(2.0 + 1e-12, 2.0) and not values.within(math.nan, 1e9)
    assert values.measurement_problem(0.5, 'j', [0.5]) == ''
    assert values.measurement_problem(None, 'j', []) == (
        f"measurement refused (joint 'j' missing, non-finite or beyond "
        f'{limits.POSITION_LIMIT_RAD} rad): []'
    )
    assert values.command_problem(20.0, 20.0) == ''
    assert values.command_problem(math.inf, 20.0) == (
        'command inf A refused (non-finite or beyond 20.0 A)'
    )
    gain_bound = limits.input_current_gain_limit(1e-3)
    assert values.estimate_problem(0.0, 0.0, 0.0, gain_bound, 20.0, 1e-3) == ('', '')
    assert values.estimate_problem(0.0, 0.0, 0.0, -1e-3, 20.0, 1e-3) == (
        'input_current_gain',
        'input_current_gain = -0.001 is negative',
    )
    field, why = values.estimate_problem(0.0, math.nan, 0.0, 0.0, 20.0, 1e-3)
    assert (field, why) == (
        'disturbance_rad_s2',
        f'disturbance_rad_s2 = nan is not finite or beyond +-{limits.DISTURBANCE_LIMIT_RAD_S2:g}',
    )


@pytest.mark.parametrize(
    'x2, x3, u, gain, field',
    [
        (1e9, 0.0, 0.0, 0.0, 'velocity_rad_s'),
        (0.0, 0.0, 21.0, 0.0, 'input_current_a'),
        (0.0, 0.0, 0.0, 1e9, 'input_current_gain'),
    ],
)
def test_an_estimate_beyond_a_bound_is_refused_by_its_field_name(x2, x3, u, gain, field):
    """Each of the estimate's fields names itself; a gain of exactly 0 is not negative."""
    from actuator_core import values

    assert values.estimate_problem(x2, x3, u, gain, 20.0, 1e-3)[0] == field
    assert values.estimate_problem(0.0, 0.0, 0.0, 0.0, 20.0, 1e-3) == ('', '')


def test_stamp_time_adopted_from_a_stamp_runs_on_with_the_monotonic_clock():
    """StampClock.adopt: that stamp is now; then the monotonic clock moves it, a wall step not."""
    from actuator_core.clock import StampClock

    host = SteppedClock()
    stamp_clock = StampClock(host)
    stamp_clock.adopt(5 * 10**9, host.now_ns())
    assert stamp_clock.now_ns() == 5 * 10**9
    host.step_wall(-(10**9))
    host.advance(1_000_000)
    assert stamp_clock.now_ns() == 5 * 10**9 + 1_000_000
    assert stamp_clock.at(host.now_ns() + 7) == 5 * 10**9 + 1_000_007


def test_injected_steps_are_read_to_the_nanosecond_and_apply_from_their_instant(monkeypatch):
    """ACTUATOR_WALL_CLOCK_STEPS 'at_s:step_s,...', sorted; a step counts from its own instant."""
    monkeypatch.setenv(clock_module.STEPS_ENV, '2:0.25, 1.5:-0.005')
    clock = Clock()
    assert clock.steps == ((1_500_000_000, -5_000_000), (2_000_000_000, 250_000_000))
    monkeypatch.setattr(clock_module.time, 'time_ns', lambda: 10**18)
    monkeypatch.setattr(clock_module.time, 'monotonic_ns', lambda: 2_000_000_000)
    assert clock.wall_ns() == 10**18 - 5_000_000 + 250_000_000
