# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The rate-limited log: one line per key and period, the suppressed ones counted, no cost."""

from actuator_ros.log import RateLimitedLog

S = 1_000_000_000


class Logger:
    """Records (severity, text) as a node's logger would print them."""

    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(('info', text))

    def warning(self, text):
        self.lines.append(('warning', text))

    def error(self, text):
        self.lines.append(('error', text))


def _log(now):
    logger = Logger()
    return logger, RateLimitedLog(logger, period_s=1.0, clock=lambda: now[0])


def test_one_line_per_key_and_period_and_the_next_line_counts_the_suppressed():
    now = [10 * S]
    logger, log = _log(now)
    for k in range(5):
        log.warn('late', lambda k=k: f'late sample {k}')
        now[0] += S // 10
    log.warn('late', lambda: 'late sample 5')  # 0.5 s after the first: still suppressed
    now[0] = 11 * S  # exactly one period after the first: logged
    log.warn('late', lambda: 'late sample 6')
    assert logger.lines == [
        ('warning', 'late sample 0'),
        ('warning', 'late sample 6 (5 more like this since the last report)'),
    ]
    assert log.counts == {'late': 7} and log.suppressed == {}


def test_keys_are_independent_and_each_severity_goes_to_its_own_call():
    now = [0]
    logger, log = _log(now)
    log.error('a', lambda: 'first a')
    log.info('b', lambda: 'first b')
    log.warn('a', lambda: 'second a')  # same key as the error: suppressed
    assert logger.lines == [('error', 'first a'), ('info', 'first b')]
    assert log.suppressed == {'a': 1}


def test_a_suppressed_message_is_never_formatted():
    now = [0]
    _, log = _log(now)
    calls = []
    log.warn('k', lambda: calls.append(1) or 'text')
    log.warn('k', lambda: calls.append(2) or 'text')
    assert calls == [1]
