# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The one process supervisor.

Start installed executables as ``ros2 run`` does, watch, stop, measure. Used by the runner
(``bringup``), the benchmark and the tests alike. A ``RosProcess`` runs in its own session (process
group), so stopping it reaches its children too: SIGINT (what Ctrl-C and ``ros2 launch`` send),
then SIGTERM, then SIGKILL; its SIGINT is at the default action even where this process ignores
SIGINT. ``ProcessFigures`` reads CPU time and peak resident memory through psutil while the
process lives.

    python -m actuator_bringup.supervisor which PACKAGE EXECUTABLE  # the path ros2 run starts
"""

from __future__ import annotations

import atexit
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import IO, Mapping, Optional, Sequence, Union

import psutil


def executable_path(package: str, executable: str) -> str:
    """``<prefix>/lib/<package>/<executable>`` as ``ros2 run <package> <executable>`` finds it.

    The prefix comes from the ament index (``get_package_prefix``); the executable is looked
    for below ``lib/<package>`` among the files the user may execute, by base name, and must
    be unique there. Raises ``PackageNotFoundError`` (from ament_index_python) or
    ``FileNotFoundError``.
    """
    from ament_index_python.packages import get_package_prefix

    base = os.path.join(get_package_prefix(package), 'lib', package)
    matches = []
    for dirpath, _dirnames, filenames in os.walk(base):
        for name in filenames:
            path = os.path.join(dirpath, name)
            if name == executable and os.path.isfile(path) and os.access(path, os.X_OK):
                matches.append(path)
    if not matches:
        raise FileNotFoundError(f'no executable {executable!r} in {base} (package {package!r})')
    if len(matches) > 1:
        raise FileNotFoundError(f'executable {executable!r} is not unique in {base}: {matches}')
    return matches[0]


_LIVE: 'set[RosProcess]' = set()


def _default_sigint() -> None:
    """In the child, before exec: SIGINT back to its default action.

    An ignored SIGINT passes through fork and exec, and a process started from a background job
    of a non-interactive shell has one: ``ros2 launch`` then never hears the SIGINT that stops
    it (launch hears signals through Python's wakeup fd, and Python sets no handler for a signal
    ignored at its start).
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class RosProcess:
    """A managed child process: an installed ROS executable or any command.

    Output goes to ``<log_dir>/<name>.stdout`` and ``.stderr``. The child runs in its own
    session (process group), so stopping it reaches its children too. Use it as a context
    manager, or call ``stop()``; the conftest fixture also stops whatever a test left
    running, and an atexit hook does the same at interpreter exit.

        with RosProcess.installed('actuator_plant', 'plant_node',
                                  ['--ros-args', '-p', 'rate_hz:=1000.0', '--params-file', f],
                                  env=ros_env, log_dir=tmp_path) as plant:
            plant.wait_for_output(r'started')
        assert plant.returncode == 0 and plant.stopped_by == 'SIGINT'
    """

    def __init__(
        self,
        cmd: Sequence[str],
        env: Optional[Mapping[str, str]] = None,
        log_dir: Optional[Union[str, Path]] = None,
        name: Optional[str] = None,
        cwd: Optional[Union[str, Path]] = None,
        start: bool = True,
    ):
        self.cmd = [str(c) for c in cmd]
        self.env = dict(os.environ if env is None else env)
        self.name = name or re.sub(r'[^A-Za-z0-9_.-]', '_', os.path.basename(self.cmd[0]))
        self.log_dir = (
            Path(log_dir) if log_dir is not None else Path(tempfile.mkdtemp(prefix='rosproc-'))
        )
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.stdout_path = self.log_dir / f'{self.name}.stdout'
        self.stderr_path = self.log_dir / f'{self.name}.stderr'
        self.cwd = cwd
        self.popen: Optional[subprocess.Popen] = None
        self.stopped_by: Optional[str] = None  # None, 'exit', 'SIGINT', 'SIGTERM' or 'SIGKILL'
        self._files: list[IO[bytes]] = []  # its stdout and stderr files, while it runs
        if start:
            self.start()

    @classmethod
    def installed(
        cls, package: str, executable: str, args: Sequence[str] = (), **kwargs
    ) -> 'RosProcess':
        """Start ``<prefix>/lib/<package>/<executable>`` with args.

        Found as ``ros2 run`` would.
        """
        kwargs.setdefault('name', f'{package}.{executable}')
        return cls([executable_path(package, executable), *args], **kwargs)

    @classmethod
    def python(cls, script: Union[str, Path], args: Sequence[str] = (), **kwargs) -> 'RosProcess':
        """Start a Python script with this interpreter (the venv's)."""
        kwargs.setdefault('name', Path(script).stem)
        return cls([sys.executable, str(script), *args], **kwargs)

    # -- life cycle -----------------------------------------------------------------------
    def start(self) -> 'RosProcess':
        if self.popen is not None:
            raise RuntimeError(f'{self.name} already started')
        out = open(self.stdout_path, 'wb')
        err = open(self.stderr_path, 'wb')
        self._files = [out, err]
        self.popen = subprocess.Popen(
            self.cmd,
            env=self.env,
            cwd=self.cwd,
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=err,
            start_new_session=True,
            preexec_fn=(  # Python code after fork only where SIGINT is ignored here
                _default_sigint if signal.getsignal(signal.SIGINT) == signal.SIG_IGN else None
            ),
        )
        _LIVE.add(self)
        return self

    @property
    def _process(self) -> subprocess.Popen:
        """The started process (``start``)."""
        assert self.popen is not None, f'{self.name} not started'
        return self.popen

    @property
    def pid(self) -> int:
        return self._process.pid

    def poll(self) -> Optional[int]:
        return None if self.popen is None else self.popen.poll()

    @property
    def running(self) -> bool:
        return self.popen is not None and self.popen.poll() is None

    @property
    def returncode(self) -> Optional[int]:
        return self.poll()

    def _ask_for_stacks(self) -> None:
        """Before SIGKILL, send SIGUSR1 to the leader: a hang at stop leaves its place in the log.

        A node of ours writes every thread's stack to its stderr on it (faulthandler, registered
        by ``run_nodes``, which starts every node process); a process without that handler ends by
        SIGUSR1.
        """
        try:
            os.kill(self._process.pid, signal.SIGUSR1)
        except ProcessLookupError:
            return
        self._wait(1.0)

    def _signal_group(self, sig: int) -> None:
        try:
            os.killpg(self._process.pid, sig)
        except ProcessLookupError:
            pass

    def _wait(self, timeout: float) -> bool:
        try:
            self._process.wait(timeout=timeout)
            return True
        except subprocess.TimeoutExpired:
            return False

    def stop(self, sigint_timeout: float = 10.0, sigterm_timeout: float = 5.0) -> Optional[int]:
        """SIGINT (what Ctrl-C and ``ros2 launch`` send), then SIGTERM, then SIGKILL.

        Each signal goes to the child's whole process group. Returns the exit code
        (negative: killed by that signal). ``stopped_by`` tells which step ended it.
        """
        if self.popen is None:
            return None
        if self.popen.poll() is None:
            for sig, timeout in (
                (signal.SIGINT, sigint_timeout),
                (signal.SIGTERM, sigterm_timeout),
                (signal.SIGKILL, 10.0),
            ):
                if sig is signal.SIGKILL:
                    self._ask_for_stacks()
                self._signal_group(sig)
                if self._wait(timeout):
                    self.stopped_by = sig.name
                    break
        elif self.stopped_by is None:
            self.stopped_by = 'exit'
        # Whatever the leader left behind in its group (grandchildren) goes too.
        self._signal_group(signal.SIGKILL)
        self._close()
        return self.popen.returncode

    def wait(self, timeout: float) -> int:
        """Wait for the process to exit by itself; on timeout stop it and raise."""
        if not self._wait(timeout):
            self.stop()
            raise TimeoutError(f'{self.name} still running after {timeout} s\n{self.describe()}')
        if self.stopped_by is None:
            self.stopped_by = 'exit'
        self._signal_group(signal.SIGKILL)
        self._close()
        return self._process.returncode

    def _close(self) -> None:
        for f in self._files:
            f.close()
        self._files = []
        _LIVE.discard(self)

    def __enter__(self) -> 'RosProcess':
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    # -- output ---------------------------------------------------------------------------
    @property
    def stdout(self) -> str:
        return self.stdout_path.read_text(errors='replace') if self.stdout_path.exists() else ''

    @property
    def stderr(self) -> str:
        return self.stderr_path.read_text(errors='replace') if self.stderr_path.exists() else ''

    @property
    def output(self) -> str:
        return self.stdout + self.stderr

    def wait_for_output(
        self, pattern: str, timeout: float = 20.0, stream: str = 'any'
    ) -> 're.Match':
        """Block until ``pattern`` (regex) appears in stdout, stderr or either ('any')."""
        rx = re.compile(pattern, re.MULTILINE)
        deadline = time.monotonic() + timeout
        while True:
            text = (
                {'stdout': self.stdout, 'stderr': self.stderr}[stream]
                if stream != 'any'
                else self.output
            )
            match = rx.search(text)
            if match:
                return match
            if not self.running:
                raise RuntimeError(
                    f'{self.name} exited ({self.returncode}) before printing '
                    f'{pattern!r}\n{self.describe()}'
                )
            if time.monotonic() > deadline:
                raise TimeoutError(
                    f'{self.name} did not print {pattern!r} within {timeout} s\n{self.describe()}'
                )
            time.sleep(0.05)

    def describe(self, tail: int = 40) -> str:
        def last(text):
            return '\n'.join(text.splitlines()[-tail:])

        return (
            f'--- {self.name}: {" ".join(self.cmd)} (pid '
            f'{self.popen.pid if self.popen else None}, '
            f'returncode {self.returncode}, stopped_by {self.stopped_by})\n'
            f'--- stdout:\n{last(self.stdout)}\n--- stderr:\n{last(self.stderr)}'
        )


def live_processes() -> 'list[RosProcess]':
    """Every RosProcess started and not yet stopped or waited for."""
    return list(_LIVE)


def stop_all_processes() -> 'list[RosProcess]':
    """Stop every RosProcess still alive; returns those that were."""
    leftovers = [p for p in list(_LIVE) if p.running]
    for proc in list(_LIVE):
        proc.stop(sigint_timeout=3.0, sigterm_timeout=2.0)
    return leftovers


atexit.register(stop_all_processes)


def process_log(folder: Union[str, Path], name: str) -> str:
    """Return what the RosProcess ``name`` wrote to ``folder``.

    stdout, then stderr: ROS logs go to stderr.
    """
    parts = [Path(folder) / f'{name}.{stream}' for stream in ('stdout', 'stderr')]
    return ''.join(p.read_text(errors='replace') for p in parts if p.is_file())


class ProcessFigures:
    """CPU (% of one core, from a mark) and peak resident memory of one process.

    Read through psutil.
    """

    def __init__(self, pid: int):
        """Watch ``pid``."""
        try:
            self.process: Optional[psutil.Process] = psutil.Process(pid)
        except psutil.Error:
            self.process = None
        self.cpu_at_mark: Optional[float] = None
        self.wall_at_mark: Optional[float] = None
        self.cpu_last = 0.0
        self.wall_last = 0.0
        self.peak_rss_mb = 0.0

    def sample(self) -> None:
        """Read CPU time and resident memory now (quietly nothing once the process is gone)."""
        if self.process is None:
            return
        try:
            with self.process.oneshot():
                times = self.process.cpu_times()
                self.cpu_last = times.user + times.system
                self.wall_last = time.monotonic()
                self.peak_rss_mb = max(self.peak_rss_mb, self.process.memory_info().rss / 2**20)
        except psutil.Error:
            pass

    def children(self) -> list:
        """Return the descendants (psutil.Process objects; empty once the process is gone)."""
        try:
            return self.process.children(recursive=True) if self.process is not None else []
        except psutil.Error:
            return []

    def mark(self) -> None:
        """Start of the measured interval (after start-up and imports)."""
        self.sample()
        self.cpu_at_mark, self.wall_at_mark = self.cpu_last, self.wall_last

    def cpu_percent(self) -> Optional[float]:
        """CPU use since ``mark`` in % of one core."""
        if (
            self.cpu_at_mark is None
            or self.wall_at_mark is None
            or self.wall_last <= self.wall_at_mark
        ):
            return None
        return 100.0 * (self.cpu_last - self.cpu_at_mark) / (self.wall_last - self.wall_at_mark)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``which PACKAGE EXECUTABLE``: print the executable's path, or one line and exit 2."""
    args = sys.argv[1:] if argv is None else list(argv)
    if len(args) != 3 or args[0] != 'which':
        print(
            'usage: python -m actuator_bringup.supervisor which PACKAGE EXECUTABLE',
            file=sys.stderr,
        )
        return 2
    from ament_index_python.packages import PackageNotFoundError

    try:
        print(executable_path(args[1], args[2]))
    except (PackageNotFoundError, FileNotFoundError) as exc:
        print(
            f'ros2run: {exc}' if str(exc) else f'ros2run: package {args[1]!r} not found',
            file=sys.stderr,
        )
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
