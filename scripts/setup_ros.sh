#!/usr/bin/env bash
# The real-rclpy tier: .venv-ros = the pinned project dependencies (requirements.txt) + ROS 2 Jazzy's
# own rclpy and message wheels (requirements-ros.txt) + active_vision_msgs, tf2_msgs and vision_msgs
# (no wheels; scripts/gen_interfaces.py writes their sources) built with cmake + the workspace
# packages (editable). `.venv-ros/bin/python` then imports the real
# rclpy (Fast DDS) and every node executable in .venv-ros/bin runs on it.
#
# Where the wheels do not exist (they are x86_64 Linux, CPython 3.10-3.13 only) this says so in one
# line, writes the reason to .venv-ros.skipped (make test prints it) and exits 0.
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=.venv-ros
SKIPPED=.venv-ros.skipped
PYTHON="${PYTHON:-python3}"
rm -f "$SKIPPED"

skip() {
  echo "setup-ros: real-rclpy tier skipped: $1"
  echo "$1" > "$SKIPPED"
  exit 0
}

[ "$(uname -s)" = Linux ] || skip "the ROS 2 Jazzy wheels are for Linux only (this is $(uname -s))"
[ "$(uname -m)" = x86_64 ] || skip "the ROS 2 Jazzy wheels are for x86_64 only (this is $(uname -m))"
pyver=$("$PYTHON" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
case "$pyver" in
  3.10|3.11|3.12|3.13) ;;
  *) skip "the ROS 2 Jazzy wheels are for CPython 3.10-3.13 (this is $pyver)";;
esac
for tool in cmake make cc c++; do
  command -v "$tool" >/dev/null || skip "building the message packages needs $tool (apt-get install cmake build-essential)"
done

if [ ! -x "$VENV/bin/python" ]; then
  echo "setup-ros: creating $VENV with $("$PYTHON" --version)"
  "$PYTHON" -m venv "$VENV"
fi
PY="$PWD/$VENV/bin/python"
"$PY" -c 'import sysconfig, os, sys; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' \
  || skip "building the message packages needs Python's headers (apt-get install python3-dev)"

# Share .venv's packages (torch, Open3D, MuJoCo, ...: about 3 GB) rather than install them a second
# time: a .pth line puts .venv's site-packages after .venv-ros's own on sys.path (the ROS wheels and
# the workspace packages installed here come first), and pip counts what it finds there as
# installed. Only with the same Python version (compiled packages are built for one).
own_site=$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
share="$own_site/_vizzy_shared_venv.pth"
rm -f "$share"
if [ -x .venv/bin/python ] && [ "$(.venv/bin/python -c 'import sys; print(sys.version_info[:2])')" \
    = "$("$PY" -c 'import sys; print(sys.version_info[:2])')" ]; then
  base_site=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
  echo "setup-ros: sharing the packages of .venv ($base_site)"
  echo "$base_site" > "$share"
fi

echo "setup-ros: installing pinned dependencies + ROS 2 Jazzy wheels (requirements.txt, requirements-ros.txt)"
"$PY" -m pip install --quiet --disable-pip-version-check -r requirements.txt -r requirements-ros.txt

# The wheels' exported CMake targets name the include directories of the machine that built them
# (/opt/python/cpXY-cpXY/...): point them at this venv's Python and numpy, inside the venv only.
prefix="$PWD/$VENV"
py_include=$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
np_include=$("$PY" -c 'import numpy; print(numpy.get_include())')
{ grep -rlE '/opt/python/cp3[0-9]+-cp3[0-9]+' "$prefix/share" --include='*.cmake' 2>/dev/null || true; } \
  | xargs -r sed -i -E \
    -e "s#/opt/python/cp3[0-9]+-cp3[0-9]+/lib/python3\.[0-9]+/site-packages/numpy/_core/include#$np_include#g" \
    -e "s#/opt/python/cp3[0-9]+-cp3[0-9]+/include/python3\.[0-9]+#$py_include#g"

build_interfaces() {  # name source_dir
  local name=$1 src=$2 build="build/ros/$1"
  echo "setup-ros: building $name (cmake, rosidl)"
  mkdir -p "$build"
  if ! (AMENT_PREFIX_PATH="$prefix" CMAKE_PREFIX_PATH="$prefix" PATH="$prefix/bin:$PATH" \
        cmake -S "$src" -B "$build" -DCMAKE_INSTALL_PREFIX="$prefix" -DCMAKE_PREFIX_PATH="$prefix" \
          -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE="$PY" \
        && AMENT_PREFIX_PATH="$prefix" PATH="$prefix/bin:$PATH" make -C "$build" -j"$(nproc)" install) \
        > "$build/build.log" 2>&1; then
    tail -n 20 "$build/build.log"
    echo "setup-ros: building $name failed; the full log is $build/build.log" >&2
    exit 1
  fi
}

for pkg in tf2_msgs vision_msgs; do
  "$PY" scripts/gen_interfaces.py "$pkg" "build/ros/${pkg}_src"
  build_interfaces "$pkg" "build/ros/${pkg}_src"
done
build_interfaces active_vision_msgs msgs

echo "setup-ros: installing the workspace packages (editable)"
for pkg in src/*/; do
  [ -f "$pkg/setup.py" ] && "$PY" -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e "$pkg"
done
"$PY" -c 'import rclpy, tf2_msgs.msg, vision_msgs.msg, active_vision_msgs.msg, vizzy_runtime.ros as r; assert r.USING_REAL_ROS' \
  || { echo "setup-ros: $VENV does not import the real rclpy and our messages" >&2; exit 1; }
echo "setup-ros: done ($VENV: real rclpy $("$PY" -c 'from importlib.metadata import version; print(version("ros-jazzy-rclpy"))'), rmw_fastrtps_cpp)"
