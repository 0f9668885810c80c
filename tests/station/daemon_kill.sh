#!/bin/sh
# kill -9 of the edge daemon in the middle of a job, then a restart on the same state
# folder: the host's `send --wait` rides over the outage (it reconnects and subscribes
# again), every defect gets exactly one outcome (the ones not finished before the kill:
# failed / aborted), and the robot never sprays a defect twice. Real processes: the
# daemon (loopback station: simulated GPIO lines, cameras replaying a rendered sequence,
# the robot simulator as its own process over Modbus TCP) and the host CLI.
#   daemon_kill.sh DENTMARK_EDGE DENTMARK
set -eu
edge=$1 host=$2
tmp=$(mktemp -d)
pid= robot= sender=
cleanup() {
  for p in $pid $robot $sender; do kill -9 "$p" 2>/dev/null || true; done
  rm -rf "$tmp"
}
trap cleanup EXIT
. "$(dirname "$0")/loopback_station.sh"
loopback_station "$tmp" 60 --record "$tmp/robot.json"
"$host" synth scan --out "$tmp/door.ply" --truth "$tmp/truth.json" --seed 5 --defects 6 >/dev/null 2>&1

port=0 runs=0
start_edge() {
  runs=$((runs + 1)); log="$tmp/edge$runs.log"
  "$edge" run --board "$tmp/board.yaml" --calibration "$tmp/cal" --state-dir "$tmp/state" --port "$port" 2>"$log" &
  pid=$!
  wait_for "$log" 'listening on port [0-9]' "the edge daemon"
  port=$(sed -n 's/.*listening on port \([0-9]*\).*/\1/p' "$log")
}
start_edge
"$host" detect "$tmp/door.ply" --out "$tmp/list.dml" --panel door-FL-0001 --job 900 --scan-time "$(date +%s.%N)" \
  >/dev/null 2>&1
"$host" send "$tmp/list.dml" --to "127.0.0.1:$port" --wait --job-timeout 180 --json "$tmp/marks.json" \
  >"$tmp/send.out" 2>"$tmp/send.err" &
sender=$!
wait_for "$tmp/send.err" ': marked' "the first mark"
kill -9 "$pid"
wait "$pid" 2>/dev/null || true
echo "daemon killed after: $(grep -c ': marked' "$tmp/send.err") mark(s)"
start_edge
grep -q 'job 900 was interrupted' "$log" || { cat "$log"; echo "no recovery logged"; exit 1; }
code=0; wait "$sender" || code=$?
sender=
cat "$tmp/send.out"
[ "$code" -eq 3 ] || { cat "$tmp/send.err"; echo "send --wait exited $code, expected 3 (not all marked)"; exit 1; }
# The same list again after the restart: acknowledged, not run again.
"$host" send "$tmp/list.dml" --to "127.0.0.1:$port" >/dev/null
sleep 1
kill -TERM "$pid"; wait "$pid" || { cat "$log"; echo "edge did not stop cleanly"; exit 1; }
pid=
kill -TERM "$robot"; wait "$robot" || true
robot=
python3 - "$tmp/marks.json" "$tmp/robot.json" <<'PY'
import json, sys
marks = json.load(open(sys.argv[1]))
robot = json.load(open(sys.argv[2]))
assert marks["complete"], "every defect has an outcome"
ids = [m["defect_id"] for m in marks["marks"]]
assert len(ids) == len(set(ids)) == marks["defects"], ids
marked = [m for m in marks["marks"] if m["outcome"] == "marked"]
aborted = [m for m in marks["marks"] if m["outcome"] == "failed" and m["reason"] == "aborted"]
others = [m for m in marks["marks"] if m not in marked and m not in aborted]
assert marked and aborted, (len(marked), len(aborted))
assert all(m["reason"] == "not_markable" for m in others), others
sprays = len(robot["sprays"])
# One spray per marked defect; at most one more, for the defect whose spray the kill cut.
assert len(marked) <= sprays <= len(marked) + 1, (sprays, len(marked))
print(f"{len(marked)} marked before the kill, {len(aborted)} reported aborted, {sprays} sprays: none twice")
PY
echo ok
