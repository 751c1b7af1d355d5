#!/usr/bin/env bash
# Set up a fresh Debian/Ubuntu machine: system libraries for headless rendering and Open3D,
# then the virtual environment at .venv with the pinned Python dependencies and our packages.
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES=(libegl1 libgl1 libosmesa6 libusb-1.0-0)
missing=()
for pkg in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing system packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

PYTHON="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv with $($PYTHON --version)"
  "$PYTHON" -m venv .venv
fi
echo "setup: installing pinned Python dependencies (requirements.txt)"
.venv/bin/python -m pip install --quiet --disable-pip-version-check -r requirements.txt
echo "setup: installing the workspace packages (editable)"
for pkg in src/*/; do
  [ -f "$pkg/setup.py" ] && .venv/bin/python -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e "$pkg"
done
echo "setup: done"
