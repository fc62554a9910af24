# The two commands of the README:
#   make demo   set up (first time) and run the main job on built-in defaults
#   make test   set up (first time) and run lint (ruff, the import contract .importlinter) + the test suite
#               + the launch tests
#               (these with ../shared/ros2-tools where it exists: scripts/launch_tests.sh)
# Both are idempotent: a second run skips finished setup steps.
SHELL := /bin/bash
VENV ?= $(CURDIR)/.venv
OUT ?= $(CURDIR)/out
PYTEST_ARGS ?=
# DDS discovery on this machine only; a domain of our own for tests.
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST

.PHONY: setup demo test launch-test lint bench clean

setup:
	@GNSS_SIM_VENV=$(VENV) scripts/setup_env.sh

demo: setup
	@scripts/run_demo.sh "$(OUT)"

lint: setup
	$(VENV)/bin/ruff check gnss_sim_ros2 test bench launch scripts
	$(VENV)/bin/lint-imports --no-cache --no-logo .importlinter

test: setup
	$(VENV)/bin/ruff check gnss_sim_ros2 test bench launch scripts
	$(VENV)/bin/lint-imports --no-cache --no-logo .importlinter
	$(VENV)/bin/python -m pytest -q -p no:cacheprovider $(PYTEST_ARGS) test
	@GNSS_SIM_VENV=$(VENV) scripts/launch_tests.sh

# the launch tests alone (real launch/launch_testing/ros2cli of ../shared/ros2-tools, in .venv-launch)
launch-test: setup
	@GNSS_SIM_VENV=$(VENV) scripts/launch_tests.sh

bench: setup
	@for b in bench/bench_*.py; do echo "== $$b"; $(VENV)/bin/python $$b --quick || exit 1; done

clean:
	rm -rf build install log .venv-launch
