#!/usr/bin/env bash
# The main job on built-in defaults (called by `make demo`): the node graph of
# sim.launch.py on the demo courtyard, the synthetic constellation of the
# default date and the demo path, 10 minutes of simulated time as fast as the
# chain answers. Output: RINEX observation/navigation files, a rosbag2 (MCAP)
# bag, skyplot.png and summary.md in $OUT.
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${GNSS_SIM_VENV:-$REPO/.venv}"
OUT="${1:-$REPO/out}"
if [ -f "$REPO/install/setup.bash" ] && [ -n "${ROS_DISTRO:-}" ]; then
  # shellcheck disable=SC1091
  set +u; source "$REPO/install/setup.bash"; set -u
fi
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
"$VENV/bin/gnss-sim" run --out "$OUT" "${@:2}"
echo "outputs in $OUT:"
ls -1 "$OUT"
