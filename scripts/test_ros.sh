#!/usr/bin/env bash
# The real-rclpy tier of `make test`: the tests marked `live` (every node live, the whole graph,
# the mixed-vendor tests) again, on ROS 2 Jazzy's own rclpy (.venv-ros, rmw_fastrtps_cpp).
# Where setup could not create .venv-ros it prints why and passes: the tier is skipped, not failed.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv-ros/bin/python ]; then
  reason="run \`make setup\` to create .venv-ros"
  [ -f .venv-ros.skipped ] && reason=$(cat .venv-ros.skipped)
  echo "real-rclpy tier skipped: $reason"
  exit 0
fi
version=$(.venv-ros/bin/python -c 'from importlib.metadata import version; print(version("ros-jazzy-rclpy"))')
echo "== real-rclpy tier: ROS 2 Jazzy rclpy $version (.venv-ros), tests marked live"
# Fast DDS binds, announces and talks on 127.0.0.1 only, discovers by unicast (no multicast), and
# reads UDP with an 8 MiB buffer (VGA images from Cyclone): the profile says why. SYSTEM_DEFAULT
# lets rmw_fastrtps take its transports from the profile (LOCALHOST adds one on every interface).
export FASTRTPS_DEFAULT_PROFILES_FILE="${FASTRTPS_DEFAULT_PROFILES_FILE:-$PWD/src/vizzy_runtime/config/fastdds_loopback.xml}"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-SYSTEM_DEFAULT}"
VIZZY_RUNTIME=ros exec .venv-ros/bin/python -m pytest -m live "$@"
