#!/usr/bin/env bash
# Sets up the ROS 2 test peer and workspace for the ros_* tests:
#   1. a Python venv (argument VENV, default .venv) with rclpy, Fast DDS, the message packages and
#      colcon from PyPI (.ci/python-ros.txt);
#   2. the fix-up the PyPI wheels need (their CMake exports name the manylinux build paths);
#   3. a colcon workspace target/colcon_ws holding this repository, built: fdavar_msgs (ament_cmake,
#      from msg/) and fdavar (ament_cargo, the node at install/fdavar/lib/fdavar/fdavar_node).
# Needs cmake and python3-dev (apt-get install -y cmake python3-dev). Idempotent.
# Env: FDAVAR_COLCON_PACKAGES="fdavar_msgs" builds only the messages (faster).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
VENV=${1:-$ROOT/.venv}
case "$VENV" in /*) ;; *) VENV=$ROOT/$VENV ;; esac

if ! command -v cmake >/dev/null; then
  echo "setup-ros: cmake is missing (apt-get install -y cmake python3-dev)" >&2
  exit 1
fi
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
if ! "$VENV/bin/python" -c "import rclpy, colcon_core, colcon_ros_cargo" 2>/dev/null; then
  "$VENV/bin/pip" install -q -r "$ROOT/.ci/python-ros.txt"
fi

# The wheels were built in a manylinux container: point their generated-Python CMake exports at
# this interpreter's headers and numpy.
PYINC=$("$VENV/bin/python" -c "import sysconfig; print(sysconfig.get_paths()['include'])")
NPINC=$("$VENV/bin/python" -c "import numpy; print(numpy.get_include())")
sed -i -E "s#/opt/python/cp3[0-9]+-cp3[0-9]+/include/python3\.[0-9]+#$PYINC#g; s#/opt/python/cp3[0-9]+-cp3[0-9]+/lib/python3\.[0-9]+/site-packages/numpy/_core/include#$NPINC#g" \
  "$VENV"/share/*/cmake/export_*__rosidl_generator_pyExport.cmake

# The workspace: src/fdavar is this repository (as a user's clone would be). colcon does not look
# inside a directory that is itself a package, so msg/ (fdavar_msgs) gets a link of its own, as
# docs/ros.md tells users to do.
WS=$ROOT/target/colcon_ws
mkdir -p "$WS/src"
ln -sfn "$ROOT" "$WS/src/fdavar"
ln -sfn "$ROOT/msg" "$WS/src/fdavar_msgs"
# Keep colcon out of build products and the venv.
for d in "$ROOT/target" "$VENV"; do touch "$d/COLCON_IGNORE"; done

# colcon-ros-cargo runs `cargo build --target-dir $WS/build/fdavar`: point that at the repository's
# own target/, and build the release profile (`--cargo-args --release`), so that the workspace build,
# `cargo run --release` and `cargo test --release` share one build of every dependency instead of
# compiling them twice (CI time budget, disk).
mkdir -p "$WS/build"
if [ ! -e "$WS/build/fdavar" ]; then ln -s "$ROOT/target" "$WS/build/fdavar"; fi

# shellcheck disable=SC1091
. "$VENV/bin/activate"
export AMENT_PREFIX_PATH=$VIRTUAL_ENV
cd "$WS"
colcon list
# shellcheck disable=SC2086
colcon build --packages-select ${FDAVAR_COLCON_PACKAGES:-fdavar_msgs fdavar} --event-handlers console_direct- \
  --cargo-args --release
test -x "$WS/install/fdavar/lib/fdavar/fdavar_node" || [ "${FDAVAR_COLCON_PACKAGES:-}" = fdavar_msgs ]
set +u
# shellcheck disable=SC1091
. "$WS/install/setup.sh"
python -c "from fdavar_msgs.msg import AxisState; print('setup-ros: fdavar_msgs importable:', AxisState.__name__)"
