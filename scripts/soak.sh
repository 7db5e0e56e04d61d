#!/usr/bin/env bash
# Soak test of the live node (issue 7): replays the bundled simulated session in a loop,
# as fast as the node takes the frames, until at least MINUTES of video at 30 fps went
# through (default 60: 108 000 frames). It samples the node's memory (RSS), open file
# descriptors and threads every INTERVAL seconds, then checks:
#   * no growth after warm-up: the last quarter's median RSS within 10 % (+ 8 MiB) of the
#     second quarter's, and no more file descriptors or threads than in the second quarter;
#   * no frame dropped or lost (none are injected here), every frame composited;
#   * the node exited cleanly.
# Writes OUT/samples.csv, OUT/soak.json and OUT/soak.md (a table and the verdict); exit
# code 0 only when every check passes.
#
# SOAK_TRANSPORT=gige plays the session over the real transports instead, in real time:
# `evarnode replay --serve-gige --serve-carm` as a GigE Vision camera on 127.0.0.1 (free
# running at 30 fps, as a grabber on the C-arm's video output) and a C-arm link on a pty,
# and the node as on the bedside box, `evarnode run --config node.json`, for MINUTES of wall
# time. Then every frame that arrived must be composited, and the GigE source must have
# lost none (its block ids have no gaps).
#
#   scripts/soak.sh [MINUTES] [OUT]        defaults: 60, out/soak
#   SOAK_INTERVAL=5                        seconds between samples
#   SOAK_TRANSPORT=replay|gige             default replay
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
minutes=${1:-60}
out=${2:-$root/out/soak}
interval=${SOAK_INTERVAL:-5}
[[ "$minutes" =~ ^[0-9]+$ ]] && [ "$minutes" -gt 0 ] || { echo "soak.sh: MINUTES must be a positive integer" >&2; exit 2; }

EVAR_TARGETS=evarnode "$root/scripts/build.sh" -DEVAR_BUILD_TESTS=OFF -DEVAR_BUILD_BENCH=OFF
bin=${EVAR_BUILD_DIR:-$root/build}/app/evarnode
mkdir -p "$out"
session=$out/session
if [ ! -f "$session/session.json" ]; then
  "$bin" sim session --seed 1 --detector-px 512 --fluoro-seconds 2 --out "$session" >/dev/null
fi
frames_per_loop=$(($(wc -l < "$session/frames/index.csv") - 1))
target_frames=$((minutes * 60 * 30))
loops=$(((target_frames + frames_per_loop - 1) / frames_per_loop))
transport=${SOAK_TRANSPORT:-replay}

rm -rf "$out/run"
server=
case "$transport" in
  replay)
    echo "soak: $loops loops of $frames_per_loop frames = $((loops * frames_per_loop)) frames ($minutes min at 30 fps), fast replay; samples every ${interval}s into $out/samples.csv"
    "$bin" run --replay "$session" --fast --loop "$loops" --no-video --no-igtl --no-progress --out "$out/run" \
      > "$out/node.log" 2>&1 &
    pid=$!
    ;;
  gige)
    camera=SOAK$$
    echo "soak: $minutes min in real time over GigE Vision camera $camera on lo and a C-arm link on $out/ttyCARM; samples every ${interval}s into $out/samples.csv"
    "$bin" replay "$session" --loop 0 --no-progress --serve-gige "$camera" --serve-carm "$out/ttyCARM" \
      > "$out/replay.log" 2>&1 &
    server=$!
    trap 'kill ${pid:-} "$server" 2>/dev/null || true' INT TERM EXIT
    python3 - "$session" "$out/node.json" "$camera" "$out/ttyCARM" <<'EOF'
import json, os, sys
session, node, camera, link = sys.argv[1:]
s = json.load(open(os.path.join(session, "session.json")))
json.dump({"format": "evarnode-node", "version": 1,
           "scene": os.path.abspath(os.path.join(session, s["scene"])),
           "registration": os.path.abspath(os.path.join(session, s["registration"])),
           "detector": s["detector"], "frames": {"camera": camera, "pixel_format": "mono16", "fps": 30},
           "carm": "serial:" + os.path.abspath(link) + ",baud=115200"}, open(node, "w"), indent=1)
EOF
    "$bin" run --config "$out/node.json" --seconds $((minutes * 60)) --no-video --no-igtl --out "$out/run" \
      > "$out/node.log" 2>&1 &
    pid=$!
    ;;
  *) echo "soak.sh: SOAK_TRANSPORT must be replay or gige" >&2; exit 2 ;;
esac
trap 'kill "$pid" ${server:+"$server"} 2>/dev/null || true' INT TERM EXIT  # now the node too
start=$(date +%s)
echo "seconds,rss_kib,fds,threads,snapshots_kib" > "$out/samples.csv"
while kill -0 "$pid" 2>/dev/null; do
  if [ -r "/proc/$pid/status" ]; then
    rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
    threads=$(awk '/^Threads:/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
    fds=$(ls "/proc/$pid/fd" 2>/dev/null | wc -l || true)
    # du still prints the total when a picture is deleted under it (the snapshot budget)
    # but then fails, which must not add a line of its own to the sample.
    snaps=$({ du -sk "$out/run/snapshots" 2>/dev/null || true; } | cut -f1)
    [ -n "$rss" ] && echo "$(($(date +%s) - start)),$rss,$fds,$threads,${snaps:-0}" >> "$out/samples.csv"
  fi
  sleep "$interval"
done
set +e
wait "$pid"
status=$?
set -e
elapsed=$(($(date +%s) - start))
if [ -n "$server" ]; then
  kill -INT "$server" 2>/dev/null || true
  wait "$server" 2>/dev/null || true
fi

python3 - "$out" "$status" "$elapsed" "$loops" "$frames_per_loop" "$transport" <<'EOF'
import csv, json, statistics, sys, platform, datetime
out, status, elapsed, loops, per_loop, transport = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]), sys.argv[6]
rows = [{k: int(v) for k, v in r.items()} for r in csv.DictReader(open(f"{out}/samples.csv"))]
checks, failures = [], []
def check(name, ok, detail):
    checks.append({"check": name, "ok": bool(ok), "detail": detail})
    if not ok: failures.append(name)
check("node exited cleanly", status == 0, f"exit status {status}")
report = {}
try:
    report = json.load(open(f"{out}/run/run_report.json"))
except Exception as e:
    check("run report written", False, str(e))
frames = report.get("frames", {})
if transport == "gige":
    # The camera free-runs at 30 fps for the run's length; what counts is that nothing that
    # came was lost on the way or in the node.
    expected = frames.get("in") or 0
    check("frames kept coming at 30 fps", expected >= 0.95 * 30 * report.get("seconds", 0),
          f"{expected} frames in {report.get('seconds', 0):.0f} s")
    check("every frame that arrived was composited", frames.get("composited") == expected,
          f"in {expected}, composited {frames.get('composited')}")
else:
    expected = loops * per_loop
    check("every frame arrived and was composited", frames.get("in") == expected and frames.get("composited") == expected,
          f"in {frames.get('in')}, composited {frames.get('composited')}, expected {expected}")
dropped = {k: frames.get(k) for k in ("dropped_input", "dropped_output", "lost_by_source", "wrong_size")}
check("no frame dropped or lost (none injected)", all(v == 0 for v in dropped.values()), json.dumps(dropped))
growth = {}
if len(rows) >= 8:
    q = len(rows) // 4
    second, last = rows[q:2 * q], rows[3 * q:]
    def med(part, key): return statistics.median(r[key] for r in part)
    rss2, rss4 = med(second, "rss_kib"), med(last, "rss_kib")
    growth = {"rss_kib_second_quarter": rss2, "rss_kib_last_quarter": rss4,
              "fds_max": [max(r["fds"] for r in second), max(r["fds"] for r in last)],
              "threads_max": [max(r["threads"] for r in second), max(r["threads"] for r in last)]}
    check("memory flat after warm-up", rss4 <= rss2 * 1.10 + 8192, f"median RSS {rss2/1024:.1f} MiB (2nd quarter) -> {rss4/1024:.1f} MiB (last quarter)")
    # A file being read or written is open for a moment; a leak grows without bound.
    check("file descriptors flat after warm-up", growth["fds_max"][1] <= growth["fds_max"][0], f"at most {growth['fds_max'][0]} (2nd quarter) -> {growth['fds_max'][1]} (last quarter)")
    check("threads flat after warm-up", growth["threads_max"][1] <= growth["threads_max"][0], f"at most {growth['threads_max'][0]} -> {growth['threads_max'][1]}")
else:
    check("enough samples", False, f"{len(rows)} samples; run longer or lower SOAK_INTERVAL")
result = {"date_utc": datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M"), "machine": platform.processor() or platform.machine(),
          "transport": transport, "video_stalls": report.get("video_stalls"), "source": report.get("source"),
          "frames": expected, "video_minutes_at_30fps": expected / 30 / 60, "wall_seconds": elapsed,
          "samples": len(rows), "growth": growth, "latency_ms": report.get("latency_ms"),
          "adaptation": report.get("adaptation"), "snapshots_kib_at_end": rows[-1]["snapshots_kib"] if rows else None,
          "checks": checks, "passed": not failures}
json.dump(result, open(f"{out}/soak.json", "w"), indent=2)
with open(f"{out}/soak.md", "w") as md:
    md.write(f"Soak ({transport}): {expected} frames ({expected/1800:.1f} min of video at 30 fps) in {elapsed} s, {len(rows)} samples\n\n")
    md.write("| check | result | detail |\n| --- | --- | --- |\n")
    for c in checks: md.write(f"| {c['check']} | {'pass' if c['ok'] else '**FAIL**'} | {c['detail']} |\n")
print(open(f"{out}/soak.md").read())
sys.exit(1 if failures else 0)
EOF
