#!/usr/bin/env bash
# The main job on the bundled example: installs what is missing, builds (Release),
# writes the synthetic aorto-iliac example scene and deforms it to contain its guidewire,
# then makes the bundled simulated session (seed 1, generated deterministically on first
# run) and replays it through the acquisition interfaces.
# Outputs: out/example/ (the scene), out/deformed/ (meshes, landmarks, report, preview),
# out/session/ (the recorded session with its ground truth), out/replay-report.json.
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
"$bin" replay "$out/session" --fast --report "$out/replay-report.json"
echo
echo "simulated session (frames, C-arm stream, ground truth):  $out/session/"
echo "what the replay delivered:                           $out/replay-report.json"
echo "deformed meshes, landmarks.mrk.json and report.json: $out/deformed/"
echo "picture of the deformation:                         $out/deformed/preview.png"
