#!/usr/bin/env bash
# Installs the Debian 12 packages evarnode builds with. Idempotent: quiet and quick when
# everything is already there. Needs root (or sudo) only when something is missing.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libembree-dev libassimp-dev libsuitesparse-dev libmetis-dev
  libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev
  libopencv-videoio-dev libopencv-highgui-dev
  libopenigtlink-dev openigtlink-examples
  libdcmtk-dev
  libvtk9-dev
  libcgal-dev
  libplplot-dev plplot-driver-cairo
  libaravis-dev aravis-tools
  libusb-1.0-0-dev umockdev libumockdev-dev
  xvfb libx11-dev libxtst-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  systemd
)
# Only the test suite needs these: a third-party reader of the PLUS export (VTK's MetaIO).
[ "${EVAR_TEST_DEPS:-0}" = 1 ] && packages+=(python3-vtk9 python3-numpy)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "evarnode: installing ${missing[*]}" >&2
sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq "${missing[@]}" >/dev/null
