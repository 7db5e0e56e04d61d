#!/usr/bin/env bash
# Installs what is missing, builds everything (Release) and runs the whole test suite.
# EVAR_SANITIZE=1 builds with AddressSanitizer + UndefinedBehaviorSanitizer instead.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
args=()
if [ "${EVAR_SANITIZE:-0}" = 1 ]; then
  export EVAR_BUILD_DIR=${EVAR_BUILD_DIR:-$root/build-asan}
  export EVAR_BUILD_TYPE=RelWithDebInfo
  args+=(-DEVAR_SANITIZE=ON)
fi
# Tests on explicitly: run-example.sh configures the same build directory without them.
"$root/scripts/build.sh" -DEVAR_BUILD_TESTS=ON "${args[@]}"
ctest --test-dir "${EVAR_BUILD_DIR:-$root/build}" --output-on-failure --no-tests=error -j"$(nproc)"
