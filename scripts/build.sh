#!/usr/bin/env bash
# Configures and builds evarnode (Release) into ${EVAR_BUILD_DIR:-build}.
# Extra arguments go to CMake (e.g. -DEVAR_SANITIZE=ON).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${EVAR_BUILD_DIR:-$root/build}
"$root/scripts/install-deps.sh"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=${EVAR_BUILD_TYPE:-Release} "$@" >/dev/null
ninja -C "$build" -j"${EVAR_JOBS:-$(nproc)}" ${EVAR_TARGETS:-}
