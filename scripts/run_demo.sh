#!/usr/bin/env bash
# The main job on built-in defaults (called by `make demo`).
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${GNSS_SIM_VENV:-$REPO/.venv}"
OUT="${1:-$REPO/out}"
if [ -f "$REPO/install/setup.bash" ] && [ -n "${ROS_DISTRO:-}" ]; then
  # shellcheck disable=SC1091
  set +u; source "$REPO/install/setup.bash"; set -u
fi
"$VENV/bin/gnss-sim" --help
"$VENV/bin/gnss-sim" roundtrip
