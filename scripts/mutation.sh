#!/usr/bin/env bash
# Mutation score of the ROS-free core (mutmut 3, pinned in requirements/python.lock): set-up,
# build, then `mutmut run` in build/mutation/ (links to the packages under src/, the tests, the
# configuration scripts/mutation/pyproject.toml), niced, and the report docs/mutation-report.md.
#   scripts/mutation.sh                       every mutant of the core (tens of minutes on 2 cores)
#   scripts/mutation.sh 'actuator_core.gate*' the mutants of one module (mutmut's name globs)
# MUTATION_JOBS (default 2) sets mutmut's --max-children; MUTATION_FRESH=1 starts from scratch
# (mutmut otherwise keeps the results of mutants whose function did not change);
# MUTATION_UNCHECKED=1 runs only the mutants of those globs that have no result yet, no test, or
# survived without an explanation in equivalent.toml (mutmut reruns every mutant a glob names),
# e.g. to finish a stopped run and judge them again against the tests written since.
# Not in CI: CPU-heavy.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
"$ROOT/scripts/build.sh"
# shellcheck source=scripts/env.sh
source "$ROOT/scripts/env.sh"

STAGE="$ROOT/build/mutation"
if [[ ${MUTATION_FRESH:-0} == 1 ]]; then
    rm -rf "$STAGE"
fi
mkdir -p "$STAGE"
cd "$STAGE"
for pkg in actuator_core actuator_controller actuator_eso actuator_plant actuator_sim; do
    ln -sfn "$ROOT/src/$pkg/$pkg" "$pkg"
done
ln -sfn "$ROOT/tests" tests
ln -sfn "$ROOT/pytest.ini" pytest.ini
ln -sfn "$ROOT/docs" docs  # tests/test_joint.py holds docs/reference/parameters.md against the specs
# The configuration with its test files filled in from the imports (test_selection.py).
python - "$ROOT/scripts/mutation/pyproject.toml" >pyproject.toml <<'PYSEL'
import subprocess
import sys

files = subprocess.run(
    [sys.executable, sys.argv[1].replace('pyproject.toml', 'test_selection.py')],
    check=True, capture_output=True, text=True,
).stdout.split()
text = open(sys.argv[1]).read()
listed = ',\n'.join(f'    "{f}"' for f in files)
print(text.replace('pytest_add_cli_args_test_selection = []',
                   f'pytest_add_cli_args_test_selection = [\n{listed},\n]'), end='')
PYSEL

# Quick tests first in each mutant's run (scripts/mutation/mutation_order.py).
export PYTHONPATH="$ROOT/scripts/mutation${PYTHONPATH:+:$PYTHONPATH}"
export PYTEST_ADDOPTS="-p mutation_order${PYTEST_ADDOPTS:+ $PYTEST_ADDOPTS}"
echo "[mutation] mutmut run $* in $STAGE (nice 19, ${MUTATION_JOBS:-2} children)"
targets=("$@")
if [[ ${MUTATION_UNCHECKED:-0} == 1 ]]; then
    mapfile -t targets < <(python "$ROOT/scripts/mutation/unchecked.py" --stage "$STAGE" "$@")
    echo "[mutation] ${#targets[@]} mutants unjudged or unexplained"
    if ((${#targets[@]} == 0)); then
        exit 0
    fi
fi
rc=0
nice -n 19 mutmut run --max-children "${MUTATION_JOBS:-2}" "${targets[@]}" || rc=$?
# A run of some modules keeps the earlier report's rows for the others (--keep-earlier).
python "$ROOT/scripts/mutation/report.py" --stage "$STAGE" --out "$ROOT/docs/mutation-report.md" \
    ${*:+--keep-earlier} \
    --command "${MUTATION_UNCHECKED:+MUTATION_UNCHECKED=$MUTATION_UNCHECKED }make mutation${*:+ ARGS='$*'}"
exit "$rc"
