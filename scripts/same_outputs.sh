#!/usr/bin/env bash
# Behaviour unchanged? The demo hour and the GPS static hour (bench --speed's two scenarios) simulated
# by a base revision and by the working tree, their RINEX observation/navigation files and fix.csv
# compared byte for byte (the RINEX 'PGM / RUN BY / DATE' line, which holds the wall-clock date, aside).
#
#   scripts/same_outputs.sh [BASE_REV] [DURATION_S]     # default: HEAD, 3600
#
# The base revision runs from a git worktree in a temporary folder with this checkout's venv (the
# package is imported from the worktree through PYTHONPATH). Exit 0 when every file is identical.
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BASE="${1:-HEAD}"
DUR="${2:-3600}"
PY="${GNSS_SIM_VENV:-$REPO/.venv}/bin/python"
TMP="$(mktemp -d)"
trap 'git -C "$REPO" worktree remove --force "$TMP/base" >/dev/null 2>&1 || true; rm -rf "$TMP"' EXIT
git -C "$REPO" worktree add --detach "$TMP/base" "$BASE" >/dev/null 2>&1

scenarios=(
  "demo|--duration $DUR"
  "gps_static|--systems G --position-ecef 3149785.9652,598260.8822,5495348.4927 --start 2025-06-01T10:00:00 --duration $DUR"
)
rc=0
for s in "${scenarios[@]}"; do
  name="${s%%|*}"; opts="${s#*|}"
  for side in base work; do
    src="$REPO"; [ "$side" = base ] && src="$TMP/base"
    # shellcheck disable=SC2086
    (cd "$src" && PYTHONPATH="$src" "$PY" -m gnss_sim_ros2.cli simulate --quiet $opts --out "$TMP/$side-$name" >/dev/null)
  done
  for f in "$TMP/base-$name"/*; do
    b="$(basename "$f")"
    [ "${b:0:1}" = "." ] && continue
    if cmp -s <(grep -v 'PGM / RUN BY / DATE' "$f") <(grep -v 'PGM / RUN BY / DATE' "$TMP/work-$name/$b" 2>/dev/null); then
      echo "same      $name/$b"
    else
      echo "DIFFERENT $name/$b"; rc=1
    fi
  done
done
exit $rc
