#!/usr/bin/env bash
# The main job on the bundled example: installs what is missing, builds (Release),
# writes the synthetic aorto-iliac example scene and deforms it to contain its guidewire.
# Outputs: out/example/ (the scene) and out/deformed/ (meshes, landmarks, report, preview).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
EVAR_TARGETS=evarnode "$root/scripts/build.sh" -DEVAR_BUILD_TESTS=OFF -DEVAR_BUILD_BENCH=OFF
bin=${EVAR_BUILD_DIR:-$root/build}/app/evarnode
out=${1:-$root/out}
"$bin" example --out "$out/example"
"$bin" deform --scene "$out/example/scene.json" --device "$out/example/device.mrk.json" --out "$out/deformed"
echo
echo "deformed meshes, landmarks.mrk.json and report.json: $out/deformed/"
echo "picture of the deformation:                         $out/deformed/preview.png"
