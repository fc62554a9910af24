#!/usr/bin/env bash
# The launch tests, with the real ROS 2 tools (launch, launch_testing, ros2cli,
# composition_interfaces) of ../shared/ros2-tools, in a layer venv on .venv:
#
#   scripts/launch_tests.sh        # called by `make test` after the main suite
#
# The layer (.venv-launch) keeps .venv as it is, so the main pytest run never
# imports launch_testing (see ros2-tools/README.md, "Why A"). gnss_sim is
# registered in the layer's ament index with executables that run the layer's
# interpreter (it has composition_interfaces); AMENT_PREFIX_PATH lists the
# layer first. On a ROS 2 install run `launch_test test/test_launch_sim.py`
# (or colcon test) instead.
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${GNSS_SIM_VENV:-$REPO/.venv}"
LAYER="${GNSS_SIM_LAUNCH_VENV:-$REPO/.venv-launch}"
KIT="${GNSS_SIM_ROS2_TOOLS:-$REPO/../shared/ros2-tools}"
cd "$REPO"
log() { printf '[launch-tests] %s\n' "$*" >&2; }

if [ ! -x "$KIT/install-into" ]; then
  log "SKIPPED: no ROS 2 launch tools at $KIT (../shared/ros2-tools sits beside the clone in CI only;"
  log "         set GNSS_SIM_ROS2_TOOLS, or on a ROS 2 install run: launch_test test/test_launch_sim.py)"
  exit 0
fi
"$KIT/install-into" --layer-on "$VENV" "$LAYER" >&2
"$LAYER/bin/python" "$REPO/scripts/ament_register.py" "$LAYER" --executables >&2
# shellcheck disable=SC1091
source "$LAYER/ros2-tools.env"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export PYTHONPATH="$REPO:$REPO/test${PYTHONPATH:+:$PYTHONPATH}"
# a domain of its own per run (0..101), away from the main suite's (101..200, test/ros_helpers.py)
domain() { echo $(( ($$ + $1) % 100 + 1 )); }

t0=$SECONDS
log "pytest (ros2 CLI, container, signals) on ROS_DOMAIN_ID=$(domain 0)"
ROS_DOMAIN_ID=$(domain 0) "$LAYER/bin/python" -m pytest -q -p no:cacheprovider \
  test/test_component_container.py test/test_launch_cli.py
# each launch test file in turn, on domains 1, 2, ... (a failure stops the script: set -e)
n=0
for name in sim rtk robots robot_layout quality_map threats fleet; do
  n=$((n + 1))
  log "launch_test test/test_launch_$name.py on ROS_DOMAIN_ID=$(domain $n)"
  ROS_DOMAIN_ID=$(domain $n) "$LAYER/bin/launch_test" "test/test_launch_$name.py"
done
log "passed in $((SECONDS - t0)) s"
