#!/usr/bin/env bash
# Fuzzes every parser that sees outside data with libFuzzer (clang, AddressSanitizer and
# UndefinedBehaviorSanitizer), each for a fixed time:
#   scripts/fuzz.sh [SECONDS_PER_HARNESS (default 60)] [HARNESS ...]
# Inputs that crash, leak, time out or run out of memory are copied into
# tests/fuzz/corpus/<harness>/ (ctest replays that folder on every run: fix the parser, then
# commit the input). The run's CPU time and result per harness go to
# build-fuzz/fuzz-report.json and are printed as a table.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
seconds=${1:-60}
shift || true
harnesses=("$@")
[ ${#harnesses[@]} -gt 0 ] || harnesses=(carm_link markups mesh scene view_geometry xa_dicom session node_config image igtl_request)
build=${EVAR_FUZZ_BUILD_DIR:-$root/build-fuzz}

if ! command -v clang++ >/dev/null || ! ls /usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a >/dev/null 2>&1; then
  echo "installing clang and libFuzzer (needs root)"
  sudo=$( [ "$(id -u)" = 0 ] || echo sudo )
  $sudo apt-get update -qq && $sudo apt-get install -y -qq clang libclang-rt-14-dev >/dev/null
fi
# The project's own build script (it installs the other dependencies), with clang.
EVAR_BUILD_DIR=$build EVAR_BUILD_TYPE=RelWithDebInfo EVAR_TARGETS="$(printf 'fuzz_%s ' "${harnesses[@]}")" \
  "$root/scripts/build.sh" -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DEVAR_FUZZ=ON -DEVAR_BUILD_BENCH=OFF

report="$build/fuzz-report.json"
echo "[" >"$report"
first=1
printf '%-14s %10s %10s %8s  %s\n' harness "cpu s" execs corpus result
for h in "${harnesses[@]}"; do
  work="$build/fuzz/$h"
  rm -rf "$work/artifacts"
  mkdir -p "$work/corpus" "$work/artifacts"
  log="$work/fuzz.log"
  set +e
  TIMEFORMAT='%U %S'
  { time ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 UBSAN_OPTIONS=print_stacktrace=1 \
      "$build/tests/fuzz/fuzz_$h" "$work/corpus" "$root/tests/fuzz/corpus/$h" \
      -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
      -artifact_prefix="$work/artifacts/" -print_final_stats=1 >"$log" 2>&1 ; } 2>"$work/time"
  status=$?
  set -e
  cpu=$(awk '{printf "%.1f", $1+$2}' "$work/time" 2>/dev/null || echo "?")
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  corpus=$(ls "$work/corpus" | wc -l)
  found=$(ls "$work/artifacts" | wc -l)
  if [ "$found" -gt 0 ]; then
    result="$found finding(s): $(ls "$work/artifacts" | tr '\n' ' ')"
    cp "$work/artifacts/"* "$root/tests/fuzz/corpus/$h/"
  elif [ $status -ne 0 ]; then
    result="exit $status (see $log)"
  else
    result="clean"
  fi
  printf '%-14s %10s %10s %8s  %s\n' "$h" "$cpu" "$execs" "$corpus" "$result"
  [ $first = 1 ] || echo "," >>"$report"
  first=0
  printf '{"harness": "%s", "seconds": %s, "cpu_s": "%s", "executions": %s, "corpus": %s, "result": "%s"}' \
    "$h" "$seconds" "$cpu" "${execs:-0}" "$corpus" "$result" >>"$report"
done
echo "]" >>"$report"
echo "report: $report"
