#!/usr/bin/env bash
# Installs what is missing, builds everything (Release) and runs the whole test suite.
# EVAR_SANITIZE=1 builds with AddressSanitizer + UndefinedBehaviorSanitizer instead (into
# build-asan, without the benchmarks) and fails on the first report.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
args=()
if [ "${EVAR_SANITIZE:-0}" = 1 ]; then
  export EVAR_BUILD_DIR=${EVAR_BUILD_DIR:-$root/build-asan}
  export EVAR_BUILD_TYPE=RelWithDebInfo
  # -O1 -g1: quicker to compile than -O2 -g, and reports keep their line numbers.
  args+=(-DEVAR_SANITIZE=ON -DEVAR_BUILD_BENCH=OFF "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g1")
  # Any report fails its test: UBSan aborts (no recovery is compiled in), ASan and LSan
  # exit non-zero; stack traces for the log.
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:strict_string_checks=1}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
  # Third-party caches held until exit (fontconfig, libltdl under PLplot), each named in the file.
  export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$root/tests/lsan.supp:print_suppressions=0}
fi
# The suite's own peers (python3-vtk9 for the PLUS export check) come with it.
export EVAR_TEST_DEPS=1
# Tests on explicitly: run-example.sh configures the same build directory without them.
"$root/scripts/build.sh" -DEVAR_BUILD_TESTS=ON "${args[@]}"
ctest --test-dir "${EVAR_BUILD_DIR:-$root/build}" --output-on-failure --no-tests=error -j"$(nproc)"
