# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The bag-test helpers (bag_helpers.py) write what they say."""

from __future__ import annotations

from pathlib import Path

from rosbags.highlevel import AnyReader

from actuator_bag.bag_format import BagWriter
from bag_helpers import COMMAND_TYPE, add_command_topic, command_cdr, synthetic_run, write_run_bag


def test_synthetic_bag_counts(tmp_path: Path) -> None:
    """The helper writes one message per sample and topic.

    Fewer joint_states where samples were dropped.
    """
    run = synthetic_run(duration_s=0.5, drop_joint=(10, 11))
    write_run_bag(tmp_path / 'run', run)
    n = run.t.size
    assert run.counts == {
        '/joint_states': n - 2,
        '/current_command': n,
        '/eso/estimate': n,
        '/controller/state': n,
        '/plant/truth': n,
    }


def test_command_cdr_reads_back_as_written(tmp_path: Path) -> None:
    """A CurrentCommand payload decodes to the stamp, current, safe_stop and frame given."""
    with BagWriter(tmp_path / 'cmd') as writer:
        handle = add_command_topic(writer, '/ns/current_command')
        writer.write(handle, 5, command_cdr(7, 1.25, safe_stop=True, sec=3, frame_id='f'))
    with AnyReader([tmp_path / 'cmd']) as reader:
        ((conn, stamp, raw),) = list(reader.messages())
        msg = reader.deserialize(raw, conn.msgtype)
    assert (conn.topic, conn.msgtype, stamp) == ('/ns/current_command', COMMAND_TYPE, 5)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (3, 7, 'f')
    assert (msg.current_a, msg.safe_stop) == (1.25, True)
