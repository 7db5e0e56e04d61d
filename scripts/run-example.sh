#!/usr/bin/env bash
# The main job on the bundled example: installs what is missing, builds (Release),
# writes the synthetic aorto-iliac example scene and deforms it to contain its guidewire,
# then makes the bundled simulated session (seed 1, generated deterministically on first
# run) and runs the live node on its replay in real time: device reconstruction from two
# views, adaptation of the vessels, the roadmap composited on every frame.
# Outputs: out/example/ (the scene), out/deformed/ (meshes, landmarks, report, preview),
# out/session/ (the recorded session with its ground truth), out/run/ (overlay video,
# before/after snapshots, run_report.json, eval.md).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
EVAR_TARGETS=evarnode "$root/scripts/build.sh" -DEVAR_BUILD_TESTS=OFF -DEVAR_BUILD_BENCH=OFF
bin=${EVAR_BUILD_DIR:-$root/build}/app/evarnode
out=${1:-$root/out}
"$bin" example --out "$out/example"
"$bin" deform --scene "$out/example/scene.json" --device "$out/example/device.mrk.json" --out "$out/deformed"
if [ ! -f "$out/session/session.json" ]; then
  "$bin" sim session --seed 1 --detector-px 512 --fluoro-seconds 2 --out "$out/session"
fi
"$bin" run --replay "$out/session" --out "$out/run"
echo
echo "simulated session (frames, C-arm stream, ground truth):  $out/session/"
echo "the live node's overlay video:                       $out/run/overlay.avi"
echo "before/after pictures of each adapted model:         $out/run/snapshots/"
echo "ostium distances, initial vs adapted:                $out/run/eval.md"
echo "counts, drops and latency (p50/p99):                 $out/run/run_report.json"
echo "deformed meshes, landmarks.mrk.json and report.json: $out/deformed/"
echo "picture of the deformation:                         $out/deformed/preview.png"
