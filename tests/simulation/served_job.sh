#!/usr/bin/env bash
# The real path between two processes: the host CLI sends a detected defect list over
# TCP to the edge daemon (running in the station's twin with the true motion, so it is
# fast), waits for every mark and writes dentmark.marks/1; the daemon's own reports and
# the host's must agree. Usage: served_job.sh DENTMARK DENTMARK_EDGE WORKDIR
set -euo pipefail
dentmark="$1" edge="$2" work="$3"
rm -rf "$work" && mkdir -p "$work"
"$dentmark" synth scan --out "$work/door.ply" --truth "$work/truth.json" --seed 11 --defects 4 >/dev/null
"$dentmark" detect "$work/door.ply" --out "$work/defects.dml" --panel door-FL --job 501 >/dev/null
"$edge" simulate --serve --port 0 --scenario A0 --truth-motion --defects "$work/defects.dml" \
  --truth "$work/truth.json" --json "$work/station.json" >"$work/edge.log" 2>&1 &
edge_pid=$!
trap 'kill "$edge_pid" 2>/dev/null || true' EXIT
port=""
for _ in $(seq 300); do
  port=$(sed -n 's/.*link: listening on port \([0-9]*\).*/\1/p' "$work/edge.log" | head -1)
  [[ -n "$port" ]] && break
  sleep 0.1
done
[[ -n "$port" ]] || { cat "$work/edge.log"; exit 1; }
# An unknown job cannot be subscribed to; a list for another panel model is refused.
"$dentmark" status "127.0.0.1:$port" | grep -q "idle"
status=0
"$dentmark" send "$work/defects.dml" --to "127.0.0.1:$port" --wait --json "$work/marks.json" \
  >"$work/host.out" 2>&1 || status=$?
cat "$work/host.out"
wait "$edge_pid"
trap - EXIT
cat "$work/edge.log"
[[ $status -eq 0 ]] || { echo "send --wait exited $status"; exit 1; }
grep -q "every defect marked" "$work/host.out"
python3 - "$work/marks.json" "$work/station.json" <<'PY'
import json, sys
marks = json.load(open(sys.argv[1]))
station = json.load(open(sys.argv[2]))["scenarios"][0]
assert marks["schema"] == "dentmark.marks/1", marks["schema"]
assert marks["job_id"] == 501 and marks["panel_id"] == "door-FL"
assert marks["complete"] and marks["all_marked"], marks
marked = [m for m in marks["marks"] if m["outcome"] == "marked"]
assert len(marked) == station["marked"] > 0, (len(marked), station["marked"])
# What the host was told is what the robot did: the twin scored every spray.
assert len(station["marks"]) == len(marked)
worst = max(abs(e) for m in station["marks"] for e in m["error_base"])
assert worst < 3e-3, worst
print(f"{len(marked)} marks reported to the host; worst axis error {worst * 1e3:.2f} mm")
PY
