#!/usr/bin/env bash
# Idempotent set-up of the project's Python/ROS environment in .venv.
#
#   * /opt/ros/jazzy present (or ACTUATOR_ROS_PREFIX pointing at a ROS 2 Jazzy install):
#     a venv with --system-site-packages over the system Python that ROS was built for;
#     only the plain Python dependencies (and colcon, if apt's is missing) go into it.
#   * otherwise: a plain venv holding ROS 2 Jazzy from the PyPI wheels (ros-*), colcon from
#     PyPI and the plain Python dependencies, then the one-time fix of the CMake paths that
#     the wheels carry from their build machine.
#
# Every version comes from requirements/*.lock and is installed with --no-deps, so nothing
# unpinned can slip in. A stamp keyed on a hash of the lock files (and of this script, the
# mode and the base Python) makes a run that finds everything up to date finish at once.
#
# Environment knobs: ACTUATOR_ROS_PREFIX (default /opt/ros/jazzy), ACTUATOR_FORCE_WHEELS=1
# (ignore a system ROS), ACTUATOR_BASE_PYTHON (interpreter for the wheel venv, Python 3.11).
set -euo pipefail
set -o errtrace

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
LOCKS="$ROOT/requirements"
STAMP="$VENV/.actuator-setup.stamp"
ENV_FILE="$VENV/actuator-env"
ROS_PREFIX="${ACTUATOR_ROS_PREFIX:-/opt/ros/jazzy}"
T0=$SECONDS

STEP="start"
step() {
    STEP="$1"
    echo "[setup] $1"
}
on_error() {
    local rc=$?
    echo "[setup] FAILED in step '$STEP': command \`$BASH_COMMAND\` exited with status $rc" \
        "(scripts/setup.sh line ${BASH_LINENO[0]})" >&2
    exit "$rc"
}
fail() {
    trap - ERR
    echo "[setup] FAILED in step '$STEP': $*" >&2
    exit 1
}
trap on_error ERR

sha_of() { sha256sum "$@" | sha256sum | cut -c1-64; }

# -------------------------------------------------------------------------------------------
step "detect ROS 2 installation"
if [[ "${ACTUATOR_FORCE_WHEELS:-0}" != 1 && -f "$ROS_PREFIX/setup.bash" ]]; then
    MODE=system
    echo "[setup]   using the system ROS 2 at $ROS_PREFIX"
else
    MODE=wheels
    echo "[setup]   no $ROS_PREFIX/setup.bash: using ROS 2 Jazzy from the PyPI wheels"
fi

step "choose base Python"
if [[ $MODE == system ]]; then
    # ROS from apt is built for the distribution's own interpreter.
    BASE_PY="${ACTUATOR_BASE_PYTHON:-/usr/bin/python3}"
else
    BASE_PY="${ACTUATOR_BASE_PYTHON:-python3}"
fi
# Resolve the interpreter with the project's own venv taken off PATH: a shell that sourced
# scripts/env.sh has .venv/bin first, and the venv's python3 is not a base interpreter.
BASE_PATH="$(printf '%s' "$PATH" | tr ':' '\n' | grep -v -x -F -e "$VENV/bin" | paste -sd: -)"
BASE_PY_CMD="$(PATH="$BASE_PATH" command -v "$BASE_PY" || true)"
[[ -n $BASE_PY_CMD ]] || fail "no Python interpreter '$BASE_PY' on PATH"
# Past any pyenv shim, and past any virtual environment to the interpreter it was made from.
BASE_PY="$(env -u VIRTUAL_ENV -u PYTHONHOME "$BASE_PY_CMD" -c 'import sys; print(getattr(sys, "_base_executable", sys.executable) if sys.prefix != sys.base_prefix else sys.executable)')"
BASE_VER="$("$BASE_PY" -c 'import sys; print("%d.%d.%d" % sys.version_info[:3])')"
if [[ $MODE == wheels && $BASE_VER != 3.11.* ]]; then
    fail "the ROS 2 Jazzy wheels are built for CPython 3.11 (cp311); $BASE_PY is $BASE_VER." \
        "Set ACTUATOR_BASE_PYTHON to a Python 3.11 interpreter."
fi
echo "[setup]   $BASE_PY ($BASE_VER)"

# The venv is tied to the mode and the interpreter; the installed set to the lock files too.
VENV_KEY="$MODE|$ROS_PREFIX|$BASE_PY|$BASE_VER"
LOCK_FILES=("$LOCKS/python.lock" "$LOCKS/colcon.lock" "$LOCKS/ros-jazzy-wheels.lock")
for f in "${LOCK_FILES[@]}"; do
    [[ -f $f ]] || fail "lock file $f is missing"
done
SETUP_KEY="$(printf '%s\n' "$VENV_KEY" | cat - "${LOCK_FILES[@]}" "${BASH_SOURCE[0]}" | sha256sum | cut -c1-64)"

step "check stamp"
if [[ -f $STAMP && "$(cat "$STAMP")" == "$SETUP_KEY" && -x $VENV/bin/python ]] \
    && "$VENV/bin/python" -c '' 2>/dev/null; then
    echo "[setup] up to date (.venv matches requirements/*.lock), $((SECONDS - T0)) s"
    exit 0
fi

# -------------------------------------------------------------------------------------------
step "check build tools"
missing=()
for tool in cmake make gcc g++ git; do
    command -v "$tool" >/dev/null || missing+=("$tool")
done
if ((${#missing[@]})); then
    fail "missing build tools: ${missing[*]} (on Debian/Ubuntu: apt-get install cmake make gcc g++ git)"
fi

step "create virtual environment"
if [[ -d $VENV && "$(cat "$VENV/.actuator-venv-key" 2>/dev/null || true)" != "$VENV_KEY" ]]; then
    echo "[setup]   .venv was made for another mode or interpreter: recreating it"
    rm -rf "$VENV"
fi
if [[ ! -x $VENV/bin/python ]]; then
    venv_args=()
    [[ $MODE == system ]] && venv_args+=(--system-site-packages)
    "$BASE_PY" -m venv "${venv_args[@]}" "$VENV" \
        || fail "'$BASE_PY -m venv' failed (on Debian/Ubuntu: apt-get install python3-venv)"
    printf '%s\n' "$VENV_KEY" >"$VENV/.actuator-venv-key"
fi
PY="$VENV/bin/python"
rm -f "$STAMP"

step "record environment for scripts/env.sh"
{
    echo "ACTUATOR_ROS_MODE=$MODE"
    echo "ACTUATOR_ROS_PREFIX=$ROS_PREFIX"
} >"$ENV_FILE"

step "select lock files"
REQ_DIR="$VENV/.actuator-requirements"
rm -rf "$REQ_DIR"
mkdir -p "$REQ_DIR"
# In system mode these come from the system whenever it has them: they must be the ones
# the system's ROS was built and tested with (numpy above all: compiled message code).
SYSTEM_FIRST=(numpy setuptools empy catkin-pkg lark-parser)
system_has=()
if [[ $MODE == wheels ]]; then
    selected=("$LOCKS/python.lock" "$LOCKS/colcon.lock" "$LOCKS/ros-jazzy-wheels.lock")
else
    selected=("$LOCKS/python.lock")
    # What the system (its site-packages, or ROS's PYTHONPATH) already provides.
    (
        ACTUATOR_ENV_NO_WORKSPACE=1 source "$ROOT/scripts/env.sh" >/dev/null
        python - "${SYSTEM_FIRST[@]}" <<'PYHAS'
import importlib.metadata as md
import importlib.util
import sys
for name in sys.argv[1:]:
    try:
        md.version(name)
        print(name)
    except md.PackageNotFoundError:
        pass
if all(importlib.util.find_spec(m) for m in ('colcon_core', 'colcon_ros', 'colcon_bash', 'colcon_cmake')):
    print('colcon')
PYHAS
    ) >"$REQ_DIR/system-provides" || fail "could not inspect the Python packages of $ROS_PREFIX"
    mapfile -t system_has <"$REQ_DIR/system-provides"
    # colcon from apt (python3-colcon-common-extensions) is visible through the system site.
    if printf '%s\n' "${system_has[@]}" | grep -qx colcon; then
        echo "[setup]   colcon: the system's"
    else
        echo "[setup]   colcon: from requirements/colcon.lock"
        selected+=("$LOCKS/colcon.lock")
    fi
fi
skip_re='^$'
if ((${#system_has[@]})); then
    skip_re="^($(printf '%s|' "${system_has[@]}" | sed 's/|$//'))=="
    echo "[setup]   from the system: ${system_has[*]}"
fi
for f in "${selected[@]}"; do
    out="$REQ_DIR/$(basename "$f")"
    grep -v -i -E "$skip_re" "$f" >"$out" || true
    echo "[setup]   $(basename "$f"): $(grep -c -E '^[^#]+==' "$out") pinned distributions"
done

step "install pinned distributions (pip --no-deps)"
req_args=()
for f in "$REQ_DIR"/*.lock; do
    req_args+=(-r "$f")
done
# (This machine's pip configuration may name local index folders that do not exist; pip's
# warnings about those are noise and are filtered. pipefail keeps pip's exit status.)
if ! { PIP_DISABLE_PIP_VERSION_CHECK=1 "$PY" -m pip install --no-deps --no-input -q "${req_args[@]}" 2>&1; } \
    | { grep -v -E "^WARNING: Location '[^']*' is ignored: it is neither a file nor a directory" || true; }; then
    fail "pip could not install the pinned set (network, or a version missing from the registry?)"
fi

step "check installed set against the locks"
if [[ $MODE == system ]]; then
    # The system's own site-packages often fail pip check for reasons of their own: report only.
    "$PY" -m pip check >/dev/null 2>&1 || echo "[setup]   note: pip check reports conflicts (system packages included):" \
        "$({ "$PY" -m pip check 2>&1 || true; } | head -5 | tr '\n' ';')"
else
    "$PY" -m pip check >/dev/null 2>&1 || {
        "$PY" -m pip check >&2 || true
        fail "pip check found broken requirements in the pinned set (see above)"
    }
fi
if [[ $MODE == wheels ]]; then
    "$PY" - "$REQ_DIR"/*.lock <<'PYCHECK'
import importlib.metadata as md
import re
import sys

def norm(name):
    return re.sub(r'[-_.]+', '-', name).lower()

pinned = {}
for path in sys.argv[1:]:
    for line in open(path):
        line = line.split('#', 1)[0].strip()
        if line:
            name, version = line.split('==')
            pinned[norm(name)] = version
installed = {}
for dist in md.distributions():
    # The ros wheels also drop *.egg-info folders of their inner packages (rclpy, std_msgs,
    # ...); those are not pip distributions (no INSTALLER) and are not pinned.
    if dist.read_text('INSTALLER'):
        installed[norm(dist.metadata['Name'])] = dist.version
problems = [f'{n}: locked {v}, installed {installed.get(n, "nothing")}'
            for n, v in pinned.items() if installed.get(n) != v]
extra = sorted(set(installed) - set(pinned) - {'pip'})
for p in problems:
    print('[setup]   mismatch:', p, file=sys.stderr)
if extra:
    print('[setup]   note: installed but not in any lock (installed by hand?):', ', '.join(extra))
sys.exit(1 if problems else 0)
PYCHECK
fi

if [[ $MODE == wheels ]]; then
    step "fix CMake paths of the ROS wheels"
    PY_INCLUDE="$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
    NUMPY_INCLUDE="$("$PY" -c 'import numpy; print(numpy.get_include())')"
    [[ -f $PY_INCLUDE/Python.h ]] || fail "no Python.h in $PY_INCLUDE (install the Python development headers)"
    [[ -d $NUMPY_INCLUDE/numpy ]] || fail "numpy's include directory $NUMPY_INCLUDE has no numpy/ headers"
    OLD_PY_INCLUDE=/opt/python/cp311-cp311/include/python3.11
    OLD_NUMPY_INCLUDE=/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include
    mapfile -d '' to_fix < <(grep -rlZ -F -e "$OLD_PY_INCLUDE" -e "$OLD_NUMPY_INCLUDE" \
        --include='*.cmake' "$VENV/share" 2>/dev/null || true)
    if ((${#to_fix[@]})); then
        sed -i -e "s#$OLD_PY_INCLUDE#$PY_INCLUDE#g" -e "s#$OLD_NUMPY_INCLUDE#$NUMPY_INCLUDE#g" "${to_fix[@]}"
        echo "[setup]   rewrote ${#to_fix[@]} CMake files under .venv/share to $PY_INCLUDE and $NUMPY_INCLUDE"
    else
        echo "[setup]   nothing to fix (already done)"
    fi
    if grep -rqF -e "$OLD_PY_INCLUDE" -e "$OLD_NUMPY_INCLUDE" --include='*.cmake' "$VENV/share"; then
        fail "the wheel builder's paths are still in .venv/share/*/cmake"
    fi
fi

step "check ROS Python"
(
    # shellcheck source=scripts/env.sh
    ACTUATOR_ENV_NO_WORKSPACE=1 source "$ROOT/scripts/env.sh"
    python -c 'import rclpy, rclpy.serialization, ament_index_python, std_msgs.msg, sensor_msgs.msg, rosgraph_msgs.msg, builtin_interfaces.msg, numpy, yaml, rosbags, mcap, matplotlib, pytest' \
        || exit 1
    python -c 'import colcon_core, colcon_ros, colcon_bash, colcon_cmake' || exit 1
) || fail "the environment does not import rclpy/colcon and the Python dependencies (see above)"

printf '%s\n' "$SETUP_KEY" >"$STAMP"
echo "[setup] done in $((SECONDS - T0)) s ($MODE mode)"
