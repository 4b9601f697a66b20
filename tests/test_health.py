# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The /diagnostics rules (actuator_core.health): levels, reasons, rates, STALE; no ROS."""

import numpy as np
import pytest

from actuator_core.health import HealthMonitor, Level, Snapshot, worst
from actuator_core.sample_log import CHUNK_ROWS, SampleLog

S = 1_000_000_000


def _monitor(**kw):
    return HealthMonitor(
        'node',
        inputs={'measurements': 'joint_states'},
        warn_on={'refused': 'refused inputs'},
        error_on={'latches': 'latches'},
        **kw,
    )


def test_levels_combine_error_over_stale_over_warn():
    assert worst([]) is Level.OK
    assert worst([Level.WARN, Level.STALE]) is Level.STALE
    assert worst([Level.STALE, Level.ERROR, Level.WARN]) is Level.ERROR
    assert [int(v) for v in Level] == [0, 1, 2, 3]  # diagnostic_msgs/DiagnosticStatus bytes


def test_active_with_moving_input_is_ok_and_reports_its_rate():
    m = _monitor()
    m.update(0, Snapshot('active', {'measurements': 0, 'refused': 0}))
    h = m.update(S // 2, Snapshot('active', {'measurements': 500, 'refused': 0}))
    assert h.level is Level.OK and h.message == 'ok'
    assert h.value('joint_states rate [Hz]') == '1000.0'
    assert h.value('measurements') == '500' and h.value('lifecycle_state') == 'active'


def test_input_that_stops_makes_the_node_stale_after_the_timeout_then_ok_again():
    m = _monitor(stale_after_s=1.0)
    m.update(0, Snapshot('active', {'measurements': 10}))
    assert m.update(S // 2, Snapshot('active', {'measurements': 10})).level is Level.OK
    h = m.update(S, Snapshot('active', {'measurements': 10}))
    assert h.level is Level.STALE and 'no joint_states for 1.0 s' in h.message
    assert m.update(3 * S // 2, Snapshot('active', {'measurements': 11})).level is Level.OK


def test_inactive_node_is_warn_and_never_stale_and_its_clock_restarts_on_activation():
    m = _monitor(stale_after_s=1.0)
    for t in range(0, 5 * S, S // 2):
        h = m.update(t, Snapshot('inactive', {'measurements': 0}))
        assert h.level is Level.WARN and h.message == 'not active (inactive)'
    # Activated at 5 s: no input for less than the timeout is not yet stale.
    assert m.update(5 * S, Snapshot('active', {'measurements': 0})).level is Level.OK
    assert m.update(6 * S, Snapshot('active', {'measurements': 0})).level is Level.STALE


def test_counters_that_moved_raise_warn_or_error_with_how_many():
    m = _monitor()
    m.update(0, Snapshot('active', {'measurements': 0, 'refused': 2, 'latches': 0}))
    h = m.update(S // 4, Snapshot('active', {'measurements': 9, 'refused': 5, 'latches': 0}))
    assert h.level is Level.WARN and h.message == '3 refused inputs since the last report'
    h = m.update(S // 2, Snapshot('active', {'measurements': 18, 'refused': 5, 'latches': 1}))
    assert h.level is Level.ERROR and h.message == '1 latches since the last report'
    # Nothing moved since: back to OK (a counter's total is no problem, its increase is).
    assert (
        m.update(
            3 * S // 4, Snapshot('active', {'measurements': 27, 'refused': 5, 'latches': 1})
        ).level
        is Level.OK
    )


def test_the_nodes_own_problems_come_first_by_severity_and_values_are_text():
    m = _monitor(stale_after_s=0.1)
    m.update(0, Snapshot('active', {'measurements': 0}))
    h = m.update(
        S,
        Snapshot(
            'active',
            {'measurements': 0},
            {'ratio': 0.123456, 'flag': True, 'none': None},
            [(Level.WARN, 'status RESYNC'), (Level.ERROR, 'latched')],
        ),
    )
    assert h.level is Level.ERROR
    assert h.message.split('; ') == ['latched', 'no joint_states for 1.0 s', 'status RESYNC']
    assert (h.value('ratio'), h.value('flag'), h.value('none')) == ('0.1235', 'true', '')


def test_bad_timeout_is_refused():
    with pytest.raises(ValueError, match='stale_after_s'):
        HealthMonitor('x', stale_after_s=0.0)


@pytest.mark.parametrize('start', [0, 5, CHUNK_ROWS - 1, CHUNK_ROWS, CHUNK_ROWS + 7, 9000, 9999])
def test_sample_log_since_gives_the_rows_appended_after_a_row(start):
    log = SampleLog(('a', 'b'))
    for k in range(9999):
        log.append((k, 2 * k))
    rows = log.since(start)
    np.testing.assert_array_equal(rows, log.array()[start:])


def test_a_prefix_rule_says_which_counter_moved():
    m = HealthMonitor('n', warn_on={'refused *': 'refused inputs'})
    m.update(0, Snapshot('active', {'refused future': 1}))
    h = m.update(S, Snapshot('active', {'refused future': 1, 'refused bad_measurement': 2}))
    assert h.level is Level.WARN
    assert h.message == '2 refused inputs (bad_measurement) since the last report'
    assert h.value('refused bad_measurement') == '2'


def test_a_report_names_its_node_and_hardware_and_counts_the_reports():
    """Health carries the monitor's name and hardware id ('' unless given); reports counted."""
    assert HealthMonitor('plain').update(0, Snapshot('active')).hardware_id == ''
    m = HealthMonitor('actuator_plant', hardware_id='cia402')
    assert m.reports == 0
    h = m.update(0, Snapshot('active'))
    m.update(S, Snapshot('active'))
    assert (h.name, h.hardware_id, m.reports) == ('actuator_plant', 'cia402', 2)


def test_rates_are_the_increase_over_the_time_between_reports_from_any_start():
    """10 samples over 0.5 s is 20 Hz, also when the monotonic clock is far from zero."""
    m = _monitor()
    m.update(100 * S, Snapshot('active', {'measurements': 5}))
    h = m.update(100 * S + S // 2, Snapshot('active', {'measurements': 15}))
    assert h.value('joint_states rate [Hz]') == '20.0'


def test_an_input_counter_the_snapshot_leaves_out_has_not_moved():
    """A missing input counter counts 0 samples: rate 0.0, and STALE once the timeout passes."""
    m = _monitor(stale_after_s=1.0)
    m.update(0, Snapshot('active', {}))
    h = m.update(S // 2, Snapshot('active', {}))
    assert h.level is Level.OK and h.value('joint_states rate [Hz]') == '0.0'
    h = m.update(S, Snapshot('active', {}))
    assert h.level is Level.STALE and 'no joint_states for 1.0 s' in h.message


def test_a_single_refusal_under_a_prefix_rule_warns_and_integers_are_shown_as_they_are():
    m = HealthMonitor('n', warn_on={'refused *': 'refused inputs'})
    m.update(0, Snapshot('active', {'refused future': 0}))
    h = m.update(S, Snapshot('active', {'refused future': 1}, {'samples': 42}))
    assert h.level is Level.WARN
    assert h.message == '1 refused inputs (future) since the last report'
    assert h.value('samples') == '42'
