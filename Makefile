# Thin wrapper: the logic lives in scripts/. Arguments for main/test/bench go in ARGS,
# e.g.  make test ARGS='-k msgs -x'
SHELL := /bin/bash
ARGS ?=

.DEFAULT_GOAL := test
.PHONY: setup build main test bench mutation clean distclean

setup:
	@bash scripts/setup.sh

build: setup
	@bash scripts/build.sh

main: setup build
	@bash scripts/main.sh $(ARGS)

test: setup build
	@bash scripts/test.sh $(ARGS)

bench: setup build
	@bash scripts/bench.sh $(ARGS)

# Mutation score of the ROS-free core into docs/mutation-report.md (hours; not in CI),
# e.g. make mutation ARGS="'actuator_core.gate*'"
mutation: setup build
	@bash scripts/mutation.sh $(ARGS)

# Build products only; `make distclean` also removes the virtual environment.
clean:
	rm -rf build install log

distclean: clean
	rm -rf .venv
