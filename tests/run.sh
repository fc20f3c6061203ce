#!/usr/bin/env bash
# The whole test suite on a fresh machine: system packages (an independent OSC peer and
# Mesa's software OpenGL through EGL), the Python packages (torch pinned to the CPU build
# by constraints.txt), then pytest. CI runs exactly this (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."

apt_packages=(liblo-tools libegl1 libegl-mesa0 libgl1-mesa-dri xvfb)
if ! dpkg -s "${apt_packages[@]}" >/dev/null 2>&1; then
  sudo=""; [ "$(id -u)" -eq 0 ] || sudo=sudo
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${apt_packages[@]}"
fi

python3 -m pip install -q -c constraints.txt -e ".[test]"
python3 -m pytest -q "$@"
