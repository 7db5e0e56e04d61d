#!/usr/bin/env bash
# The deformation stage alone against the synthetic patients' ground truth (3D, no
# imaging): for each seed, `evarnode sim patient`, then `evarnode deform` with the true
# device and the default options, then the 3D distance of every landmark to its true
# position, before (preoperative) and after. Seeds the generator refuses are listed, not
# counted. Writes OUT/deform_eval.json (per seed and landmark) and OUT/deform_eval.md (the
# table of docs/SYNTHETIC_PATIENTS.md) and prints the table.
#
#   scripts/deform-eval.sh [FIRST LAST] [OUT]     defaults: 1 20, out/deform-eval
#   EVAR_DIFFICULTY=mild|paper EVAR_PHYSICS=beam|conforming   the patients (default mild, beam)
#   EVAR_DEFORM_OPTIONS="--nearest-pairing ..."                 extra `evarnode deform` options
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
first=${1:-1}
last=${2:-20}
out=${3:-$root/out/deform-eval}
[[ "$first" =~ ^[0-9]+$ && "$last" =~ ^[0-9]+$ ]] && [ "$first" -le "$last" ] ||
  { echo "deform-eval.sh: FIRST and LAST must be seed numbers, FIRST <= LAST" >&2; exit 2; }

EVAR_TARGETS=evarnode "$root/scripts/build.sh" -DEVAR_BUILD_TESTS=OFF -DEVAR_BUILD_BENCH=OFF
bin=${EVAR_BUILD_DIR:-$root/build}/app/evarnode
mkdir -p "$out"
refused=()
failed=()
for seed in $(seq "$first" "$last"); do
  dir=$out/seed-$seed
  # A patient made earlier is kept only if it is of the difficulty and physics asked for.
  if [ -f "$dir/patient/patient.json" ] &&
    ! grep -q "\"difficulty\": \"${EVAR_DIFFICULTY:-mild}\"" "$dir/patient/patient.json" ||
    { [ -f "$dir/patient/patient.json" ] && ! grep -q "\"physics\": \"${EVAR_PHYSICS:-beam}\"" "$dir/patient/patient.json"; }; then
    rm -rf "$dir"
  fi
  if [ ! -f "$dir/patient/scene.json" ]; then
    rm -rf "$dir"
    if ! "$bin" sim patient --seed "$seed" --difficulty "${EVAR_DIFFICULTY:-mild}" --physics "${EVAR_PHYSICS:-beam}" \
      --out "$dir/patient" > "$dir.log" 2>&1; then
      refused+=("$seed")
      continue
    fi
  fi
  if "$bin" deform --scene "$dir/patient/scene.json" --device "$dir/patient/device.mrk.json" --out "$dir/deformed" \
    --no-preview ${EVAR_DEFORM_OPTIONS:-} >> "$dir.log" 2>&1; then
    echo "seed $seed: deformed" >&2
  else
    failed+=("$seed")
    rm -rf "$dir/deformed"
    echo "seed $seed: deform FAILED (see $dir.log)" >&2
  fi
done

python3 - "$out" "$first" "$last" "${refused[*]:-}" "${failed[*]:-}" <<'EOF'
import json, math, os, statistics, sys
out, first, last, refused, failed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4].split(), sys.argv[5].split()

def points(path):
    m = json.load(open(path))["markups"][0]
    flip = m.get("coordinateSystem", "LPS") == "RAS"
    return {p["label"]: [(-c if flip and i < 2 else c) for i, c in enumerate(p["position"])] for p in m["controlPoints"]}

rows, cases = {}, []
for seed in range(first, last + 1):
    d = os.path.join(out, f"seed-{seed}")
    if str(seed) in refused or not os.path.exists(os.path.join(d, "deformed", "landmarks.mrk.json")):
        continue
    carrier = json.load(open(os.path.join(d, "patient", "patient.json")))["device"]["iliac"]
    before, after = points(os.path.join(d, "patient", "landmarks.mrk.json")), points(os.path.join(d, "deformed", "landmarks.mrk.json"))
    truth = points(os.path.join(d, "patient", "truth", "landmarks.mrk.json"))
    case = {"seed": seed, "carrier": carrier, "landmarks": {}}
    for label, t in truth.items():
        b, a = math.dist(before[label], t), math.dist(after[label], t)
        side = label.rsplit("_", 1)[-1]
        group = ("renal ostia" if label.startswith("renal") else
                 "internal iliac ostium of the carrier iliac" if carrier.endswith(side) else
                 "internal iliac ostium of the other iliac")
        rows.setdefault(group, []).append((b, a, seed))
        case["landmarks"][label] = {"before_mm": b, "after_mm": a}
    cases.append(case)

order = ["internal iliac ostium of the carrier iliac", "internal iliac ostium of the other iliac", "renal ostia"]
lines = [f"Seeds {first}-{last} ({len(cases)} deformed; refused by the generator: {', '.join(refused) or 'none'}; "
         f"deform failed: {', '.join(failed) or 'none'}), default options, "
         "3D distance (mm) of each landmark to its true position, before (preoperative) and after `deform`:", "",
         "| landmark | n | mean before | mean after | median after | better / worse (by more than 0.5 mm) | worst after |",
         "| --- | --- | --- | --- | --- | --- | --- |"]
summary = {}
for g in order:
    r = rows.get(g, [])
    if not r:
        continue
    b = [x[0] for x in r]; a = [x[1] for x in r]
    better = sum(1 for x in r if x[1] < x[0] - 0.5); worse = sum(1 for x in r if x[1] > x[0] + 0.5)
    worst = max(r, key=lambda x: x[1])
    summary[g] = {"n": len(r), "mean_before_mm": statistics.mean(b), "mean_after_mm": statistics.mean(a),
                  "median_after_mm": statistics.median(a), "better": better, "worse": worse}
    lines.append(f"| {g} | {len(r)} | {statistics.mean(b):.2f} | **{statistics.mean(a):.2f}** | {statistics.median(a):.2f} | "
                 f"{better} / {worse} | {worst[1]:.2f} (seed {worst[2]}, before {worst[0]:.2f}) |")
json.dump({"seeds": [first, last], "refused": refused, "failed": failed, "summary": summary, "cases": cases},
          open(os.path.join(out, "deform_eval.json"), "w"), indent=1)
open(os.path.join(out, "deform_eval.md"), "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
EOF
[ ${#failed[@]} -eq 0 ] || { echo "deform-eval.sh: deform failed for seed(s) ${failed[*]}" >&2; exit 1; }
