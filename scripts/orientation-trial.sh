#!/usr/bin/env bash
# Does the node say when the video mapping misses a mirror or a turn of the picture, and
# only then? For each seed and each way a display may show the picture, `evarnode sim
# session --video-out` renders a session as the monitor shows it; the node replays it
# twice: with the session's mapping (right), and with the same mapping missing the turn and
# mirror (wrong). Counts the sessions in which the screen said "PICTURE ... ?" (run_report
# analysis.orientation_alerts), and of those with the wrong mapping, the ones whose last
# alert named the display's own mirror and rotation as the fix or another fix, and prints
# the table of
# docs/FORMATS.md, "Is the picture the right way round?". Sessions the generator refuses
# are listed, not counted.
#
#   scripts/orientation-trial.sh [FIRST LAST] [OUT]      defaults: 1 8, out/orientation-trial
#   EVAR_DIFFICULTY=mild|paper EVAR_PHYSICS=beam|conforming   the patients (default paper, beam)
#   EVAR_TURNS="0:true 90:false 180:false 270:true"          rotation_deg:mirror of the displays
#   EVARNODE=/path/to/evarnode                                 that binary, nothing built
#   EVAR_RUN_OPTIONS="--no-pelvis"                             extra `evarnode run` options
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
first=${1:-1}
last=${2:-8}
out=${3:-$root/out/orientation-trial}
[[ "$first" =~ ^[0-9]+$ && "$last" =~ ^[0-9]+$ ]] && [ "$first" -le "$last" ] ||
  { echo "orientation-trial.sh: FIRST and LAST must be seed numbers, FIRST <= LAST" >&2; exit 2; }
difficulty=${EVAR_DIFFICULTY:-paper}
physics=${EVAR_PHYSICS:-beam}
turns=${EVAR_TURNS:-0:true 90:false 180:false 270:true}

if [ -n "${EVARNODE:-}" ]; then
  bin=$EVARNODE
else
  EVAR_TARGETS=evarnode "$root/scripts/build.sh" -DEVAR_BUILD_TESTS=OFF -DEVAR_BUILD_BENCH=OFF
  bin=${EVAR_BUILD_DIR:-$root/build}/app/evarnode
fi
mkdir -p "$out"
results=$out/results.tsv
: > "$results"
for seed in $(seq "$first" "$last"); do
  for turn in $turns; do
    rotation=${turn%%:*}
    mirror=${turn##*:}
    name=seed-$seed-r$rotation-m$mirror
    dir=$out/$name
    rm -rf "$dir"
    mkdir -p "$dir"
    # A 640 x 512 monitor, the 512 px picture in the middle, one line of text left of it.
    cat > "$dir/mapping.json" <<EOF
{"format": "evarnode-video-mapping", "version": 1, "video_size_px": [640, 512], "image_rect_px": [80, 0, 512, 512],
 "mirror": $mirror, "rotation_deg": $rotation, "field_shape": "rectangle", "text_regions_px": [[4, 4, 70, 20]]}
EOF
    if ! "$bin" sim session --seed "$seed" --detector-px 512 --fluoro-seconds 1 --difficulty "$difficulty" \
      --physics "$physics" --video-out "$dir/mapping.json" --out "$dir/session" --no-progress > "$dir/sim.log" 2>&1; then
      echo "seed $seed, display $turn: the generator refused (see $dir/sim.log)" >&2
      printf '%s\t%s\t%s\trefused\t\t\n' "$seed" "$rotation" "$mirror" >> "$results"
      continue
    fi
    for mapping in right wrong; do
      if [ "$mapping" = wrong ]; then  # the mapping as if the display showed the picture as it is
        python3 - "$dir/session/session.json" <<'EOF'
import json, sys
path = sys.argv[1]
session = json.load(open(path))
session["video_mapping"]["mirror"] = False
session["video_mapping"]["rotation_deg"] = 0
json.dump(session, open(path, "w"), indent=2)
EOF
      fi
      "$bin" run --replay "$dir/session" --fast --no-igtl --no-progress --no-video --out "$dir/run-$mapping" ${EVAR_RUN_OPTIONS:-} \
        > "$dir/run-$mapping.log" 2>&1 || { echo "seed $seed, display $turn, $mapping mapping: run FAILED (see $dir/run-$mapping.log)" >&2; exit 1; }
      python3 - "$dir/run-$mapping/run_report.json" "$seed" "$rotation" "$mirror" "$mapping" >> "$results" <<'EOF'
import json, sys
a = json.load(open(sys.argv[1]))["analysis"]
print("\t".join(sys.argv[2:6] + [str(a["orientation_alerts"]), a["last_orientation_alert"].replace("\t", " ")]))
EOF
    done
    rm -rf "$dir/session"
    echo "seed $seed, display rotation $rotation mirror $mirror: done" >&2
  done
done

python3 - "$results" "$difficulty" "$physics" "${EVAR_RUN_OPTIONS:+, run ${EVAR_RUN_OPTIONS}}" <<'EOF'
import collections, sys
rows = [line.rstrip("\n").split("\t") for line in open(sys.argv[1]) if line.strip()]
table = collections.OrderedDict()
refused = []
for seed, rotation, mirror, mapping, alerts, said in rows:
    key = (rotation, mirror)
    if mapping == "refused":
        refused.append(f"seed {seed} ({rotation}, {mirror})")
        continue
    t = table.setdefault(key, {"right": [0, 0, 0, 0], "wrong": [0, 0, 0, 0]})
    t[mapping][0] += 1
    t[mapping][1] += int(alerts) > 0
    right_fix = f'"mirror": {mirror}, "rotation_deg": {rotation} (it has false, 0)' in said
    t[mapping][2] += right_fix
    t[mapping][3] += "would need" in said and not right_fix
print(f"{sys.argv[2]} difficulty, {sys.argv[3]} physics{sys.argv[4]}\n")
print("| display | sessions | said, right mapping (false alarms) | said, mapping missing the turn | naming the display's turn as the fix | naming another fix |")
print("|---|---|---|---|---|---|")
for (rotation, mirror), t in table.items():
    shown = ("turned " + rotation + "°" if rotation != "0" else "") + (" and " if rotation != "0" and mirror == "true" else "") + ("mirrored" if mirror == "true" else "")
    print(f"| {shown} | {t['right'][0]} | {t['right'][1]} | {t['wrong'][1]} | {t['wrong'][2]} | {t['wrong'][3]} |")
if refused:
    print("\nrefused by the generator: " + ", ".join(refused))
EOF
