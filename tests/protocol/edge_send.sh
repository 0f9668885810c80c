#!/bin/sh
# End to end over loopback, host and edge as separate processes: the edge daemon runs
# on a loopback station (simulated GPIO lines, cameras replaying a rendered sequence,
# the robot simulator as its own process over Modbus TCP), `dentmark send` delivers
# golden lists (unsigned, then signed with a key on both sides), the daemon stores and
# acks them, `dentmark status` reads its state, and SIGTERM stops it with exit code 0.
#   edge_send.sh DENTMARK_EDGE DENTMARK DATA_DIR
set -eu
edge=$1 host=$2 data=$3
tmp=$(mktemp -d)
pid= robot=
cleanup() {
  [ -n "$pid" ] && kill "$pid" 2>/dev/null
  [ -n "$robot" ] && kill "$robot" 2>/dev/null
  rm -rf "$tmp"
}
trap cleanup EXIT

# The station: a short rendered sequence, its panel model taught, identity transforms.
"$host" synth stereo --out "$tmp/seq" --seconds 3 --width 640 --height 512 --focal 870 >/dev/null
mkdir -p "$tmp/cal/models"
cp "$tmp/seq/stereo.yaml" "$tmp/cal/stereo.yaml"
"$edge" teach --sequence "$tmp/seq" --out "$tmp/cal/models/door-FL-0001.yaml" 2>/dev/null
for t in robot:T_base_camL scanner:T_camL_sls; do
  printf '%%YAML:1.0\n---\n%s: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1. ]\nrms: 0.\n' \
    "${t#*:}" >"$tmp/cal/${t%%:*}.yaml"
done
"$host" robot-sim --port 0 >"$tmp/robot.log" 2>&1 &
robot=$!
i=0
while ! grep -qs 'listening on [0-9.]*:[0-9]' "$tmp/robot.log"; do
  i=$((i + 1)); [ $i -gt 100 ] && { cat "$tmp/robot.log"; echo "robot simulator did not start"; exit 1; }
  sleep 0.1
done
robot_port=$(sed -n 's/.*listening on [0-9.]*:\([0-9][0-9]*\).*/\1/p' "$tmp/robot.log" | head -1)
cat >"$tmp/board.yaml" <<YAML
board: { vendor: test, name: loopback }
cpu: { arch: x86_64 }
gpio:
  backend: sim
  sprayer_valve: { line: "sprayer-valve" }
  estop: { line: "estop", active_low: true }
camera: { backend: replay, left: "$tmp/seq", width: 640, height: 512 }
modbus: { transport: tcp, host: "127.0.0.1", port: $robot_port }
link: { port: 7878 }
limits: { workspace_min: [-1, -1, 0], workspace_max: [1, 1, 1], max_speed: 0.25, max_acceleration: 1.0 }
YAML

runs=0
start_edge() {  # args: extra options
  # A fresh log each run: the background shell truncates it only once it has forked,
  # and a reused one could still show the last run's port.
  runs=$((runs + 1)); log="$tmp/edge$runs.log"
  "$edge" run --board "$tmp/board.yaml" --calibration "$tmp/cal" --state-dir "$tmp/state$runs" --port 0 "$@" \
    2>"$log" &
  pid=$!
  i=0
  while ! grep -qs 'listening on port [0-9]' "$log"; do
    i=$((i + 1)); [ $i -gt 200 ] && { cat "$log"; echo "edge did not start"; exit 1; }
    sleep 0.1
  done
  port=$(sed -n 's/.*listening on port \([0-9]*\).*/\1/p' "$log")
}
stop_edge() {
  kill -TERM "$pid"
  code=0; wait "$pid" || code=$?
  pid=
  [ "$code" -eq 0 ] || { cat "$log"; echo "edge exit code $code"; exit 1; }
}

start_edge
"$host" status "127.0.0.1:$port" >"$tmp/status"
grep -q '^edge 127.0.0.1:[0-9]*: idle, faults: none$' "$tmp/status" || { cat "$tmp/status"; exit 1; }
"$host" send "$data/defect_list.dml" --to "127.0.0.1:$port" >"$tmp/out"
grep -q '^ack job 42: 2 defects, sequence [0-9]*, digest [0-9a-f]\{64\} (matches)$' "$tmp/out" || { cat "$tmp/out"; exit 1; }
[ -s "$tmp/state1/jobs/42/list.dml" ] || { echo "the list was not stored"; exit 1; }
# A frame that is not a defect list is refused: exit 1, reason printed.
if "$host" send "$data/ack.dml" --to "127.0.0.1:$port" 2>"$tmp/err"; then echo "ack.dml accepted"; exit 1; fi
# A list for a panel model the station was never taught is refused, naming the model.
if "$host" send "$data/defect_list_empty.dml" --to "127.0.0.1:$port" 2>"$tmp/err"; then echo "no model accepted"; exit 1; fi
grep -q 'names no panel model' "$tmp/err" || { cat "$tmp/err"; exit 1; }
stop_edge
grep -q "job 42 panel 'door-FL-0001': 2 defects accepted" "$log" || { cat "$log"; exit 1; }
grep -q 'signal 15 received; stopping' "$log"

start_edge --key "$data/golden.key"
# Without the key: refused as unauthenticated.
if "$host" send "$data/defect_list.dml" --to "127.0.0.1:$port" 2>"$tmp/err"; then echo "unsigned accepted"; exit 1; fi
grep -q 'unauthenticated' "$tmp/err" || { cat "$tmp/err"; exit 1; }
"$host" send "$data/defect_list_signed.dml" --to "127.0.0.1:$port" --key "$data/golden.key" >"$tmp/out"
grep -q '(matches), authenticated$' "$tmp/out" || { cat "$tmp/out"; exit 1; }
stop_edge
echo "ok"
