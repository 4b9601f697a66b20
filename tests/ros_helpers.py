"""Shared test tooling: isolated ROS domains, installed executables, managed processes.

Everything here expects the project environment (``source scripts/env.sh``; ``make test``
does it). The pytest fixtures built on it live in ``tests/conftest.py``.

Isolation: each test gets its own ``ROS_DOMAIN_ID``, reserved through a lock file so that
parallel pytest processes on the same machine never share one, and discovery restricted to
this host (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, no static peers, no discovery
server, no deprecated ``ROS_LOCALHOST_ONLY``).
"""

from __future__ import annotations

import atexit
import errno
import fcntl
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Iterable, Mapping, Optional, Sequence, Union

#: Domain ids handed out to tests. Fast DDS derives its UDP ports from the domain id; up to
#: 101 they stay below Linux's ephemeral port range (ROS 2 "The ROS_DOMAIN_ID" concept page).
#: 0 (everybody's default) is left out.
DOMAIN_ID_RANGE = range(1, 102)

#: Variables that decide whom a ROS process can discover. ``isolated_ros_env`` sets or
#: removes every one of them.
ISOLATION_SET = ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_STATIC_PEERS')
ISOLATION_UNSET = ('ROS_LOCALHOST_ONLY', 'ROS_DISCOVERY_SERVER', 'ROS_SUPER_CLIENT')

WORKSPACE = Path(__file__).resolve().parent.parent
_LOCK_DIR = Path(tempfile.gettempdir()) / 'actuator-ros-domain-locks'


class DomainReservation:
    """Holds one ROS domain id, exclusively among all processes of this machine.

    The search starts at an offset derived from the pid (so consecutive or parallel runs
    start apart) and takes the first id whose lock file can be locked. The lock is an
    advisory ``flock`` that the kernel drops when the process dies, so a crashed run never
    leaks a reservation.
    """

    _counter = 0

    def __init__(self, exclude: Iterable[int] = ()):
        _LOCK_DIR.mkdir(parents=True, exist_ok=True)
        ids = list(DOMAIN_ID_RANGE)
        DomainReservation._counter += 1
        start = (os.getpid() * 7 + DomainReservation._counter * 13) % len(ids)
        excluded = set(exclude)
        for k in range(len(ids)):
            domain_id = ids[(start + k) % len(ids)]
            if domain_id in excluded:
                continue
            fd = os.open(_LOCK_DIR / f'{domain_id}.lock', os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                os.close(fd)
                if exc.errno in (errno.EAGAIN, errno.EACCES):
                    continue
                raise
            os.ftruncate(fd, 0)
            os.write(fd, f'{os.getpid()}\n'.encode())
            self.domain_id = domain_id
            self._fd: Optional[int] = fd
            return
        raise RuntimeError(f'every ROS domain id in {DOMAIN_ID_RANGE} is taken by other tests')

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # drops the flock
            self._fd = None

    def __enter__(self) -> 'DomainReservation':
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def isolated_ros_env(domain_id: int, base: Optional[Mapping[str, str]] = None,
                     log_dir: Optional[Union[str, Path]] = None) -> dict:
    """An environment for a ROS subprocess that sees only processes of ``domain_id`` on this host."""
    env = dict(os.environ if base is None else base)
    for name in ISOLATION_UNSET:
        env.pop(name, None)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['ROS_STATIC_PEERS'] = ''
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    # Output reaches the capture files at once, without colour codes.
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_LOGGING_BUFFERED_STREAM'] = '0'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    if log_dir is not None:
        env['ROS_LOG_DIR'] = str(log_dir)
    return env


def check_project_environment() -> Optional[str]:
    """None when scripts/env.sh is in effect, otherwise what is missing."""
    if not os.environ.get('ACTUATOR_WS'):
        return 'ACTUATOR_WS is not set'
    prefixes = os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
    install = str(WORKSPACE / 'install')
    if not any(p.startswith(install) for p in prefixes):
        return f'AMENT_PREFIX_PATH has no package of {install} (not built, or install/setup.bash not sourced)'
    return None


def env_without_workspace(env: Mapping[str, str], workspace: Union[str, Path] = WORKSPACE) -> dict:
    """``env`` minus everything the workspace overlay (install/, build/) added to it.

    Leaves the underlay (venv or /opt/ros/jazzy) in place, so that another checkout can be
    built with the same tools without seeing this workspace's packages.
    """
    ws = str(Path(workspace).resolve())
    owned = (os.path.join(ws, 'install'), os.path.join(ws, 'build'))
    out = {}
    for key, value in env.items():
        if key.startswith('COLCON_'):
            continue
        entries = value.split(os.pathsep)
        kept = [p for p in entries if not any(p == o or p.startswith(o + os.sep) for o in owned)]
        if len(kept) != len(entries):
            if not kept:
                continue
            value = os.pathsep.join(kept)
        out[key] = value
    return out


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

    def __init__(self, cmd: Sequence[str], env: Optional[Mapping[str, str]] = None,
                 log_dir: Optional[Union[str, Path]] = None, name: Optional[str] = None,
                 cwd: Optional[Union[str, Path]] = None, start: bool = True):
        self.cmd = [str(c) for c in cmd]
        self.env = dict(os.environ if env is None else env)
        self.name = name or re.sub(r'[^A-Za-z0-9_.-]', '_', os.path.basename(self.cmd[0]))
        self.log_dir = Path(log_dir) if log_dir is not None else Path(tempfile.mkdtemp(prefix='rosproc-'))
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.stdout_path = self.log_dir / f'{self.name}.stdout'
        self.stderr_path = self.log_dir / f'{self.name}.stderr'
        self.cwd = cwd
        self.popen: Optional[subprocess.Popen] = None
        self.stopped_by: Optional[str] = None  # None, 'exit', 'SIGINT', 'SIGTERM' or 'SIGKILL'
        self._files = []
        if start:
            self.start()

    @classmethod
    def installed(cls, package: str, executable: str, args: Sequence[str] = (), **kwargs) -> 'RosProcess':
        """Start ``<prefix>/lib/<package>/<executable>`` (found as ``ros2 run`` would) with args."""
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
        self.popen = subprocess.Popen(self.cmd, env=self.env, cwd=self.cwd, stdin=subprocess.DEVNULL,
                                      stdout=out, stderr=err, start_new_session=True)
        _LIVE.add(self)
        return self

    @property
    def pid(self) -> int:
        return self.popen.pid

    def poll(self) -> Optional[int]:
        return None if self.popen is None else self.popen.poll()

    @property
    def running(self) -> bool:
        return self.popen is not None and self.popen.poll() is None

    @property
    def returncode(self) -> Optional[int]:
        return self.poll()

    def _signal_group(self, sig: int) -> None:
        try:
            os.killpg(self.popen.pid, sig)
        except ProcessLookupError:
            pass

    def _wait(self, timeout: float) -> bool:
        try:
            self.popen.wait(timeout=timeout)
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
            for sig, timeout in ((signal.SIGINT, sigint_timeout), (signal.SIGTERM, sigterm_timeout),
                                 (signal.SIGKILL, 10.0)):
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
        return self.popen.returncode

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

    def wait_for_output(self, pattern: str, timeout: float = 20.0, stream: str = 'any') -> 're.Match':
        """Block until ``pattern`` (regex) appears in stdout, stderr or either ('any')."""
        rx = re.compile(pattern, re.MULTILINE)
        deadline = time.monotonic() + timeout
        while True:
            text = {'stdout': self.stdout, 'stderr': self.stderr}.get(stream) if stream != 'any' else self.output
            match = rx.search(text)
            if match:
                return match
            if not self.running:
                raise RuntimeError(f'{self.name} exited ({self.returncode}) before printing '
                                   f'{pattern!r}\n{self.describe()}')
            if time.monotonic() > deadline:
                raise TimeoutError(f'{self.name} did not print {pattern!r} within {timeout} s\n{self.describe()}')
            time.sleep(0.05)

    def describe(self, tail: int = 40) -> str:
        def last(text):
            return '\n'.join(text.splitlines()[-tail:])
        return (f'--- {self.name}: {" ".join(self.cmd)} (pid {self.popen.pid if self.popen else None}, '
                f'returncode {self.returncode}, stopped_by {self.stopped_by})\n'
                f'--- stdout:\n{last(self.stdout)}\n--- stderr:\n{last(self.stderr)}')


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


# -- messages ---------------------------------------------------------------------------------
_INT_RANGES = {
    'int8': (-2**7, 2**7 - 1), 'uint8': (0, 2**8 - 1),
    'int16': (-2**15, 2**15 - 1), 'uint16': (0, 2**16 - 1),
    'int32': (-2**31, 2**31 - 1), 'uint32': (0, 2**32 - 1),
    'int64': (-2**63, 2**63 - 1), 'uint64': (0, 2**64 - 1),
    'octet': (0, 255), 'byte': (0, 255), 'char': (0, 255),
}
_ARRAY_RE = re.compile(r'^(?P<base>.+?)\[(?P<size>\d+)\]$')
_SEQ_RE = re.compile(r'^sequence<(?P<base>.+?)(?:,\s*(?P<bound>\d+))?>$')
_STR_RE = re.compile(r'^(?P<kind>w?string)(?:<(?P<bound>\d+)>)?$')


class _Counter:
    def __init__(self, seed: int):
        self.k = seed

    def next(self) -> int:
        self.k += 1
        return self.k


def _scalar(type_name: str, counter: _Counter):
    k = counter.next()
    if type_name in ('double', 'float', 'float64', 'float32', 'long double'):
        return k + 0.25 + (k % 7) * 0.5  # exactly representable in float32 for small k
    if type_name in ('boolean', 'bool'):
        return True  # the default is False
    if type_name in _INT_RANGES:
        lo, hi = _INT_RANGES[type_name]
        value = 1 + (k * 37) % min(hi, 250)
        if type_name in ('octet', 'byte'):
            return bytes([value])
        if type_name == 'char':
            return chr(value % 127 or 65)  # rclpy's char is a 1-character str
        if hi >= 2**63 - 1:
            value += 2**32 + 7  # 64-bit types: beyond 32 bits, to catch truncation
        return value
    m = _STR_RE.match(type_name)
    if m:
        text = f'v{k}-éx' if m.group('kind') == 'wstring' else f'v{k}-x'
        bound = m.group('bound')
        return text[:int(bound)] if bound else text
    raise ValueError(f'no test value for type {type_name!r}')


def fill_message(msg, seed: int = 0):
    """Set every field of ``msg`` (recursively) to a value that differs from its default.

    Driven by ``get_fields_and_field_types()``, so a field added to a .msg file later is
    covered without touching the tests. Values depend on ``seed`` and on the field order
    only, so two processes that fill the same type with the same seed agree exactly.
    Returns ``msg``.
    """
    _fill(msg, _Counter(seed * 1000))
    return msg


def _fill(msg, counter: _Counter) -> None:
    for field, type_name in msg.get_fields_and_field_types().items():
        current = getattr(msg, field)
        setattr(msg, field, _value_for(type_name, current, counter))


def _value_for(type_name: str, current, counter: _Counter):
    m = _ARRAY_RE.match(type_name)
    if m:
        size = int(m.group('size'))
        items = [_value_for(m.group('base'), _element_template(current, m.group('base')), counter)
                 for _ in range(size)]
        return items
    m = _SEQ_RE.match(type_name)
    if m:
        bound = m.group('bound')
        size = min(3, int(bound)) if bound else 3
        return [_value_for(m.group('base'), _element_template(current, m.group('base')), counter)
                for _ in range(size)]
    if '/' in type_name:  # nested message: fill a fresh instance of the field's class
        nested = type(current)() if current is not None and not isinstance(current, (list, tuple)) \
            else _message_class(type_name)()
        _fill(nested, counter)
        return nested
    value = _scalar(type_name, counter)
    return value


def _element_template(current, base_type: str):
    if '/' in base_type:
        return _message_class(base_type)()
    return None


def _message_class(type_name: str):
    """'pkg/Type' or 'pkg/msg/Type' to the Python class."""
    import importlib
    parts = type_name.split('/')
    pkg, name = parts[0], parts[-1]
    return getattr(importlib.import_module(f'{pkg}.msg'), name)


def message_leaves(msg, prefix: str = '') -> dict:
    """Flatten a message into {'field.sub[2].x': plain value} (numbers, bools, str, bytes as ints)."""
    out = {}
    for field, type_name in msg.get_fields_and_field_types().items():
        _leaves(getattr(msg, field), f'{prefix}{field}', out)
    return out


def _leaves(value, path: str, out: dict) -> None:
    if hasattr(value, 'get_fields_and_field_types'):
        out.update(message_leaves(value, path + '.'))
        return
    if isinstance(value, (bytes, bytearray)):
        out[path] = list(value)
        return
    if isinstance(value, str):
        out[path] = value
        return
    try:
        items = list(value)  # lists, array.array, numpy arrays
    except TypeError:
        out[path] = value.item() if hasattr(value, 'item') else value
        return
    for i, item in enumerate(items):
        _leaves(item, f'{path}[{i}]', out)
    if not items:
        out[path] = []


def leaves_equal(a: dict, b: dict) -> 'list[str]':
    """Differences between two ``message_leaves`` dicts (empty when identical; NaN == NaN)."""
    diffs = []
    for key in sorted(set(a) | set(b)):
        if key not in a or key not in b:
            diffs.append(f'{key}: only in {"first" if key in a else "second"}')
            continue
        x, y = a[key], b[key]
        same = x == y or (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y))
        if not same:
            diffs.append(f'{key}: {x!r} != {y!r}')
    return diffs


def interface_types(package: str, kind: str = 'msg') -> 'list[str]':
    """Names of the ``kind`` interfaces a package registered in the ament index."""
    from ament_index_python.resources import get_resource

    content, _ = get_resource('rosidl_interfaces', package)
    names = set()
    for line in content.splitlines():
        path = line.split(';')[0].strip()
        if path.startswith(f'{kind}/') and (path.endswith(f'.{kind}') or path.endswith('.idl')):
            names.add(Path(path).stem)
    return sorted(names)


def wait_until(predicate, timeout: float, interval: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())
