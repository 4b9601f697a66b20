#!/usr/bin/env bash
# colcon build of src/ into build/, install/ and log/ (symlink install: edits to Python
# modules under src/ take effect without a rebuild; new entry points, launch or config
# files need one, and this script notices them).
#
# Skipped when nothing changed since the last successful build: the key is a hash of the
# content of every file under src/ and interfaces/ that git tracks or would track (untracked,
# not ignored), of the lock files, of this script, of the set-up stamp and of where
# control_msgs comes from. Extra arguments go to `colcon build` and force a build (e.g.
# scripts/build.sh --packages-select actuator_msgs).
#
# interfaces/control_msgs (what FollowJointTrajectory needs, in the Jazzy release's layout) is
# built only when the environment has no control_msgs of its own: a Jazzy install with
# ros-jazzy-control-msgs keeps its own, and a copy built here before is then removed from
# install/ so it cannot shadow it.
set -euo pipefail
set -o errtrace

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
STAMP="$ROOT/install/.actuator-build.stamp"
T0=$SECONDS

STEP="start"
step() {
    STEP="$1"
    echo "[build] $1"
}
on_error() {
    local rc=$?
    echo "[build] FAILED in step '$STEP': command \`$BASH_COMMAND\` exited with status $rc" \
        "(scripts/build.sh line ${BASH_LINENO[0]})" >&2
    exit "$rc"
}
trap on_error ERR

step "hash sources"
list_sources() {
    if git -C "$ROOT" rev-parse --is-inside-work-tree >/dev/null 2>&1; then
        git -C "$ROOT" ls-files -z --cached --others --exclude-standard -- src interfaces
    else
        find src interfaces -type f -not -path '*/__pycache__/*' -print0
    fi
}

step "find control_msgs"
# The ament prefixes of the environment before this workspace's overlay (a shell that sourced
# scripts/env.sh carries install/ in AMENT_PREFIX_PATH already: it does not count).
installed_control_msgs() {
    (
        ACTUATOR_ENV_NO_WORKSPACE=1 source "$ROOT/scripts/env.sh" >/dev/null
        local prefix
        IFS=':' read -r -a prefixes <<<"${AMENT_PREFIX_PATH:-}"
        for prefix in "${prefixes[@]}"; do
            [[ -z $prefix || $prefix == "$ROOT/install"* ]] && continue
            if [[ -f $prefix/share/ament_index/resource_index/packages/control_msgs ]]; then
                echo "$prefix"
                return 0
            fi
        done
    )
}
CONTROL_MSGS_PREFIX="$(installed_control_msgs || true)"
if [[ -n $CONTROL_MSGS_PREFIX ]]; then
    echo "[build]   control_msgs: installed in $CONTROL_MSGS_PREFIX (interfaces/control_msgs not built)"
    BASE_PATHS=(src)
else
    echo "[build]   control_msgs: none installed, building interfaces/control_msgs"
    BASE_PATHS=(src interfaces)
fi
# Deleted-but-tracked files are listed by git too: hash only what exists.
BUILD_KEY="$(
    {
        list_sources | sort -z | while IFS= read -r -d '' f; do
            if [[ -f $f ]]; then sha256sum -- "$f"; else echo "deleted $f"; fi
        done
        sha256sum requirements/*.lock scripts/build.sh
        cat .venv/.actuator-setup.stamp 2>/dev/null || echo "no setup stamp"
        echo "control_msgs from ${CONTROL_MSGS_PREFIX:-interfaces/control_msgs}"
    } | sha256sum | cut -c1-64
)"

if [[ $# -eq 0 && -f $STAMP && -f install/setup.bash && "$(cat "$STAMP")" == "$BUILD_KEY" ]]; then
    echo "[build] up to date (src/ unchanged since the last build), $((SECONDS - T0)) s"
    exit 0
fi

step "source environment (without the workspace overlay)"
# shellcheck source=scripts/env.sh
ACTUATOR_ENV_NO_WORKSPACE=1 source "$ROOT/scripts/env.sh"

step "colcon build"
rm -f "$STAMP"
if [[ -n $CONTROL_MSGS_PREFIX && -d install/control_msgs ]]; then
    echo "[build]   removing the control_msgs built here before: the installed one is used"
    rm -rf install/control_msgs build/control_msgs
fi
# colcon is run with the venv's interpreter so the installed executables' shebang is the
# venv's python (which sees the venv's packages), also when colcon itself comes from apt.
if ! python -c 'import sys; sys.argv[0] = "colcon"; from colcon_core.command import main; sys.exit(main())' \
    --log-base log build \
    --base-paths "${BASE_PATHS[@]}" \
    --build-base build \
    --install-base install \
    --symlink-install \
    "$@" \
    --cmake-args -DBUILD_TESTING=OFF; then
    trap - ERR
    echo "[build] FAILED in step 'colcon build': see the package output above and log/latest_build/" >&2
    exit 1
fi

printf '%s\n' "$BUILD_KEY" >"$STAMP"
echo "[build] done in $((SECONDS - T0)) s"
