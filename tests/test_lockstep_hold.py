# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The sim lockstep's start-up hold (actuator_ros.lockstep_hold), with a publisher stand-in."""

import pytest

from actuator_ros.lockstep_hold import LockstepHold


class Publisher:
    """What LockstepHold uses of an rclpy publisher: publish and the matched readers."""

    def __init__(self, readers=0):
        self.readers = readers
        self.sent = []

    def publish(self, msg):
        self.sent.append(msg)

    def get_subscription_count(self):
        return self.readers


def test_messages_wait_for_every_reader_then_go_in_order():
    pub = Publisher(readers=1)  # the recorder matched first: not yet the controller
    hold = LockstepHold(pub, 2)
    hold.publish('x0')
    hold.publish('x1')
    assert pub.sent == []
    pub.readers = 2
    hold.on_matched()
    assert pub.sent == ['x0', 'x1']


def test_a_reader_counted_at_publish_time_releases_without_an_event():
    pub = Publisher(readers=1)
    hold = LockstepHold(pub, 2)
    hold.publish('x0')
    pub.readers = 2  # matched between the event and the next publish
    hold.publish('x1')
    assert pub.sent == ['x0', 'x1']


def test_once_released_a_reader_leaving_holds_nothing():
    pub = Publisher(readers=2)
    hold = LockstepHold(pub, 2)
    hold.publish('x0')
    pub.readers = 1  # the recorder ended
    hold.on_matched()
    hold.publish('x1')
    assert pub.sent == ['x0', 'x1']


@pytest.mark.parametrize('subscribers', [0, -1])
def test_no_count_never_holds(subscribers):
    pub = Publisher(readers=0)
    hold = LockstepHold(pub, subscribers)
    hold.publish('u0')
    assert pub.sent == ['u0']


def test_an_event_below_the_count_releases_nothing():
    pub = Publisher(readers=0)
    hold = LockstepHold(pub, 3)
    hold.publish('u0')
    pub.readers = 2
    hold.on_matched()
    assert pub.sent == [] and hold.unsent == ['u0']


def test_the_publishers_count_decides_not_the_events():
    # an in-process recording (actuator_bag.tap) is a reader that no matched event reports
    pub = Publisher(readers=1)
    hold = LockstepHold(pub, 3)
    hold.publish('x0')
    pub.readers = 3  # the event says 2, the recording the third
    hold.on_matched(object())
    assert pub.sent == ['x0']
