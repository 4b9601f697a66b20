#!/usr/bin/env bash
# The main job: set-up, build, then `python -m actuator_bringup.main [arguments]`.
# (The module actuator_bringup.main is written by the bring-up work.)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
"$ROOT/scripts/build.sh"
# shellcheck source=scripts/env.sh
source "$ROOT/scripts/env.sh"
cd "$ROOT"
exec python -m actuator_bringup.main "$@"
