# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Real-time settings (actuator_ros/realtime.py): read before rclpy.init, checked, applied."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from actuator_ros import realtime
from actuator_ros.realtime import RealtimeSettings, pre_init_settings

NODE = 'actuator_controller'


def test_defaults_are_valid_and_change_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    """No priority, no pinning: no problem, no system call, no note."""
    calls = []
    monkeypatch.setattr(realtime.os, 'sched_setaffinity', lambda *a: calls.append(a))
    monkeypatch.setattr(realtime.os, 'sched_setscheduler', lambda *a: calls.append(a))
    settings = RealtimeSettings()
    assert settings.problems() == [] and settings.cpus() == set()
    assert settings.apply() is None and calls == []


@pytest.mark.parametrize(
    'settings, message',
    [
        (
            RealtimeSettings(thread_priority=100),
            "parameter 'thread_priority' = 100 refused: an integer in [0, 99]",
        ),
        (
            RealtimeSettings(thread_priority=-1),
            "parameter 'thread_priority' = -1 refused: an integer in [0, 99]",
        ),
        (
            RealtimeSettings(thread_priority='50'),
            "parameter 'thread_priority' = '50' refused: an integer in [0, 99]",
        ),
        (
            RealtimeSettings(nice=20),
            "parameter 'nice' = 20 refused: an integer in [-20, 19]",
        ),
        (
            RealtimeSettings(nice=-21),
            "parameter 'nice' = -21 refused: an integer in [-20, 19]",
        ),
        (
            RealtimeSettings(executor='multi_threaded'),
            "parameter 'executor' = 'multi_threaded' refused: one of events, single_threaded",
        ),
        (
            RealtimeSettings(cpu_affinity='0;1'),
            "parameter 'cpu_affinity' = '0;1' refused: a comma-separated CPU list such as "
            '"1" or "0,1"',
        ),
    ],
)
def test_each_bad_value_is_one_exact_line(settings: RealtimeSettings, message: str) -> None:
    """Every invalid field gives exactly its own refusal line."""
    assert settings.problems() == [message]


def test_boundaries_are_accepted() -> None:
    """Priority 0 and 99, a single CPU with spaces, both executors: valid."""
    for settings in (
        RealtimeSettings(thread_priority=0),
        RealtimeSettings(thread_priority=99, cpu_affinity=' 1 ', executor='single_threaded'),
    ):
        assert settings.problems() == []
    assert RealtimeSettings(cpu_affinity='0,1').cpus() == {0, 1}
    assert RealtimeSettings(cpu_affinity=' 1 ').cpus() == {1}


def test_apply_pins_then_raises_the_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """Affinity to the given CPUs and SCHED_FIFO at the given priority, both for this process."""
    calls = []
    monkeypatch.setattr(realtime.os, 'sched_setaffinity', lambda *a: calls.append(('aff', *a)))
    monkeypatch.setattr(
        realtime.os,
        'sched_setscheduler',
        lambda pid, policy, param: calls.append(('fifo', pid, policy, param.sched_priority)),
    )
    assert RealtimeSettings(thread_priority=51, cpu_affinity='1').apply() is None
    assert calls == [('aff', 0, {1}), ('fifo', 0, os.SCHED_FIFO, 51)]


def test_kernel_refusals_are_one_note_each(monkeypatch: pytest.MonkeyPatch) -> None:
    """Both refused: one joined note naming each refusal and the normal scheduling it keeps."""

    def refuse(*_):
        raise PermissionError(1, 'Operation not permitted')

    monkeypatch.setattr(realtime.os, 'sched_setaffinity', refuse)
    monkeypatch.setattr(realtime.os, 'sched_setscheduler', refuse)
    note = RealtimeSettings(thread_priority=50, cpu_affinity='7').apply()
    assert note == (
        "cpu_affinity '7' refused by the kernel ([Errno 1] Operation not permitted); not pinned; "
        'SCHED_FIFO priority 50 refused by the kernel ([Errno 1] Operation not permitted); '
        'running with normal scheduling (grant CAP_SYS_NICE or an rtprio limit to enable it)'
    )


def test_apply_really_pins_a_process() -> None:
    """In a child process: apply() with one allowed CPU leaves the process on exactly that CPU."""
    cpu = min(os.sched_getaffinity(0))
    code = textwrap.dedent(
        f"""
        import os
        from actuator_ros.realtime import RealtimeSettings
        assert RealtimeSettings(cpu_affinity='{cpu}').apply() is None
        print(sorted(os.sched_getaffinity(0)))
        """
    )
    out = subprocess.run(
        [sys.executable, '-c', code], capture_output=True, text=True, timeout=60, check=True
    )
    assert out.stdout.strip() == f'[{cpu}]'


def test_apply_really_lowers_a_process_and_says_why_it_cannot_raise_one() -> None:
    """In a child process without privileges: nice 10 is taken; raising it back is one note.

    (From this process's niceness if that is above 10: a child may only go lower.)
    """
    lower = min(19, max(10, os.getpriority(os.PRIO_PROCESS, 0)))
    code = textwrap.dedent(
        f"""
        import os
        from actuator_ros.realtime import RealtimeSettings
        assert RealtimeSettings(nice={lower}).apply() is None
        print(os.getpriority(os.PRIO_PROCESS, 0))
        print(RealtimeSettings(nice={lower - 5}).apply())
        """
    )
    unprivileged = []
    if os.geteuid() == 0:  # root may raise it: drop to nobody, as a user's node runs
        if not shutil.which('setpriv'):
            pytest.skip('running as root without setpriv: no unprivileged child to refuse')
        unprivileged = ['setpriv', '--reuid=65534', '--regid=65534', '--clear-groups']
    out = subprocess.run(
        [*unprivileged, sys.executable, '-c', code],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
        env={**os.environ, 'HOME': '/tmp'},
    )
    niceness, note = out.stdout.strip().splitlines()
    assert int(niceness) == lower
    assert note.startswith(f'nice {lower - 5} refused by the kernel (')
    assert note.endswith(f'); running at nice {lower}')


def test_command_line_values_are_parsed_as_rcl_does() -> None:
    """-p values are YAML scalars; the cpu list stays text; names of other parameters ignored."""
    settings = pre_init_settings(
        [
            '--ros-args',
            '-p', 'thread_priority:=50',
            '-p', 'cpu_affinity:=1',
            '--param', 'executor:=single_threaded',
            '-p', 'mode:=realtime',
            '-p', 'nice:=3',
        ],
        NODE,
    )  # fmt: skip
    assert settings == RealtimeSettings(50, '1', 'single_threaded', 3)


def test_node_prefixed_values_apply_to_that_node_only() -> None:
    """'-p other_node:thread_priority:=60' is not this node's; '-p this_node:...' is."""
    args = ['--ros-args', '-p', 'actuator_eso:thread_priority:=60']
    assert pre_init_settings(args, NODE).thread_priority == 0
    assert pre_init_settings(args, 'actuator_eso').thread_priority == 60
    args = ['--ros-args', '-p', f'{NODE}:thread_priority:=61']
    assert pre_init_settings(args, NODE).thread_priority == 61


def test_arguments_outside_ros_args_are_not_read() -> None:
    """Before --ros-args and after its closing '--', -p belongs to the program, not to rcl."""
    args = ['-p', 'thread_priority:=10', '--ros-args', '--', '-p', 'thread_priority:=20']
    assert pre_init_settings(args, NODE) == RealtimeSettings()


def test_parameter_files_node_section_over_wildcard_and_later_wins(tmp_path: Path) -> None:
    """'/**' then the node's own section; a later -p overrides the file, a later file the -p."""
    params = tmp_path / 'p.yaml'
    params.write_text(
        textwrap.dedent(
            f"""
            /**:
              ros__parameters:
                thread_priority: 40
                cpu_affinity: 0
                executor: single_threaded
            {NODE}:
              ros__parameters:
                thread_priority: 45
            actuator_eso:
              ros__parameters:
                thread_priority: 70
            """
        )
    )
    from_file = pre_init_settings(['--ros-args', '--params-file', str(params)], NODE)
    assert from_file == RealtimeSettings(45, '0', 'single_threaded')
    later_p = ['--ros-args', '--params-file', str(params), '-p', 'thread_priority:=47']
    assert pre_init_settings(later_p, NODE).thread_priority == 47
    later_file = ['--ros-args', '-p', 'thread_priority:=47', '--params-file', str(params)]
    assert pre_init_settings(later_file, NODE).thread_priority == 45


def test_unreadable_parameter_file_is_left_to_rcl(tmp_path: Path) -> None:
    """A missing or unparsable file yields no setting here (rcl reports it with its own error)."""
    bad = tmp_path / 'bad.yaml'
    bad.write_text('a: [unclosed\n')
    for path in (tmp_path / 'missing.yaml', bad):
        args = ['--ros-args', '-p', 'thread_priority:=5', '--params-file', str(path)]
        assert pre_init_settings(args, NODE) == RealtimeSettings(thread_priority=5)


@pytest.mark.parametrize(
    'args, sim',
    [
        ([], False),  # a node run alone: real time
        (['--ros-args', '-p', 'mode:=realtime'], False),
        (['--ros-args', '-p', 'mode:=sim'], True),
        (['--ros-args', '-p', 'use_sim_time:=true'], True),  # the recorder's way
        (['--ros-args', '-p', f'{NODE}:mode:=sim'], True),  # a composed process
        (['--ros-args', '-p', 'actuator_eso:mode:=sim'], False),  # another node's
        (['--ros-args', '-p', 'mode:=sim', '-p', 'mode:=realtime'], False),
    ],
)
def test_sim_time_is_read_from_the_nodes_own_arguments(args, sim) -> None:
    """Only real time gets the UDP-only transport (a lockstep has no deadline to miss)."""
    assert realtime.in_sim_time(args, NODE) is sim


@pytest.mark.parametrize(
    'sim, fifo, mode',
    [
        (True, False, 'SYNCHRONOUS'),  # a lockstep saves the sending thread's wake-up
        (True, True, 'SYNCHRONOUS'),
        (False, True, 'ASYNCHRONOUS'),  # the sending thread runs at once under SCHED_FIFO
        (False, False, 'SYNCHRONOUS'),  # normal scheduling: no hand-off to wait a slice for
    ],
)
def test_the_publication_mode_follows_time_and_scheduling(sim, fifo, mode) -> None:
    assert realtime.publication_mode(sim, fifo) == mode


def test_sim_time_from_a_parameter_file_section(tmp_path: Path) -> None:
    """The node's section of a file (as launch_ros writes one) says sim."""
    params = tmp_path / 'p.yaml'
    params.write_text(f'{NODE}:\n  ros__parameters:\n    mode: sim\n')
    args = ['--ros-args', '--params-file', str(params)]
    assert realtime.in_sim_time(args, NODE)
    assert not realtime.in_sim_time(args, 'actuator_eso')
