#!/usr/bin/env bash
# Set-up, build, then the test suite: python -m pytest tests [pytest arguments].
# pytest's exit code 5 (no test collected) counts as a failure. The slowest 30 tests' durations
# are printed, and the last line is the real-time ledger (tests/conftest.py): reruns and host
# skips per test; a run whose host skips exceed the stated share fails with it.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
"$ROOT/scripts/build.sh"
# shellcheck source=scripts/env.sh
source "$ROOT/scripts/env.sh"
cd "$ROOT"

echo "[test] python -m pytest tests $*"
ledger="$(mktemp)"
trap 'rm -f "$ledger"' EXIT
rc=0
ACTUATOR_TEST_LEDGER="$ledger" python -m pytest tests -ra --durations=30 "$@" || rc=$?
if [[ $rc -eq 5 ]]; then
    echo "[test] FAILED: pytest collected no tests (exit 5), which counts as a failure" >&2
    exit 1
fi
if [[ -s $ledger ]]; then
    line="$(python -c 'import json, sys; d = json.load(open(sys.argv[1])); print(d["line"]); sys.exit(3 if d["too_many_host_skips"] else 0)' "$ledger")" || {
        echo "[test] FAILED: too many host skips: $line"
        exit 1
    }
    echo "[test] $line"
else
    echo "[test] real-time ledger: no real-time test ran"
fi
exit "$rc"
