#!/usr/bin/env bash
# Sets a fresh Debian/Ubuntu machine up for fdavar's tests and interop checks:
#   - cmake (colcon builds the fdavar_msgs interface package),
#   - a Python venv in .venv with the independent peers the tests use: PyPI `rosbags` and
#     `mcap-ros2-support` (bag writers), and the real ROS 2 client stack (`ros-rclpy`, Fast DDS, colcon)
#     listed in .ci/python-*.txt,
#   - the fix-ups those ROS wheels need (.ci/setup-ros.sh).
# Idempotent: re-running it only installs what is missing. The Rust build needs nothing from here.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
command -v cmake >/dev/null 2>&1 || need_apt+=(cmake)
python3 -c 'import sysconfig,os,sys; sys.exit(0 if os.path.exists(os.path.join(sysconfig.get_paths()["include"],"Python.h")) else 1)' \
  || need_apt+=(python3-dev)
if ((${#need_apt[@]})); then
  if [ "$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi
  echo "setup: installing ${need_apt[*]} with apt-get"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  python3 -m venv .venv
fi
reqs=()
for f in .ci/python-*.txt; do [ -f "$f" ] && reqs+=(-r "$f"); done
if ((${#reqs[@]})); then
  echo "setup: pip install ${reqs[*]}"
  .venv/bin/pip install -q --disable-pip-version-check "${reqs[@]}"
fi
if [ -f .ci/setup-ros.sh ]; then
  bash .ci/setup-ros.sh .venv
fi
echo "setup: done (tests find Python at .venv/bin/python; override with FDAVAR_PYTHON)"
