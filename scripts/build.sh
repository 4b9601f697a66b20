#!/usr/bin/env bash
# colcon build of src/ into build/, install/ and log/ (symlink install: edits to Python
# modules under src/ take effect without a rebuild; new entry points, launch or config
# files need one, and this script notices them).
#
# Skipped when nothing changed since the last successful build: the key is a hash of the
# content of every file under src/ that git tracks or would track (untracked, not ignored),
# of the lock files, of this script and of the set-up stamp. Extra arguments go to
# `colcon build` and force a build (e.g. scripts/build.sh --packages-select actuator_msgs).
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
        git -C "$ROOT" ls-files -z --cached --others --exclude-standard -- src
    else
        find src -type f -not -path '*/__pycache__/*' -print0
    fi
}
# Deleted-but-tracked files are listed by git too: hash only what exists.
BUILD_KEY="$(
    {
        list_sources | sort -z | while IFS= read -r -d '' f; do
            if [[ -f $f ]]; then sha256sum -- "$f"; else echo "deleted $f"; fi
        done
        sha256sum requirements/*.lock scripts/build.sh
        cat .venv/.actuator-setup.stamp 2>/dev/null || echo "no setup stamp"
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
# colcon is run with the venv's interpreter so the installed executables' shebang is the
# venv's python (which sees the venv's packages), also when colcon itself comes from apt.
if ! python -c 'import sys; sys.argv[0] = "colcon"; from colcon_core.command import main; sys.exit(main())' \
    --log-base log build \
    --base-paths src \
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
