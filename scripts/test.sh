#!/usr/bin/env bash
# Set-up, build, then the test suite: python -m pytest tests [pytest arguments].
# pytest's exit code 5 (no test collected) counts as a failure.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
"$ROOT/scripts/build.sh"
# shellcheck source=scripts/env.sh
source "$ROOT/scripts/env.sh"
cd "$ROOT"

echo "[test] python -m pytest tests $*"
rc=0
python -m pytest tests -ra "$@" || rc=$?
if [[ $rc -eq 5 ]]; then
    echo "[test] FAILED: pytest collected no tests (exit 5), which counts as a failure" >&2
    exit 1
fi
exit "$rc"
