#!/usr/bin/env bash
# Benchmarks: set-up, build, then `python -m actuator_bench.bench [arguments]`.
# (The module actuator_bench.bench is written by the performance work.)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
"$ROOT/scripts/build.sh"
# shellcheck source=scripts/env.sh
source "$ROOT/scripts/env.sh"
cd "$ROOT"
exec python -m actuator_bench.bench "$@"
