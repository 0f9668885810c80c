#!/bin/sh
# End to end over loopback: dentmark-edge listens on a free port, `dentmark send`
# delivers golden lists (unsigned, then signed with a key on both sides), the daemon
# acks, and SIGTERM stops it with exit code 0.
#   edge_send.sh DENTMARK_EDGE DENTMARK BOARD_FILE DATA_DIR
set -eu
edge=$1 host=$2 board=$3 data=$4
tmp=$(mktemp -d)
pid=
cleanup() { [ -n "$pid" ] && kill "$pid" 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT

runs=0
start_edge() {  # args: extra options
  # A fresh log each run: the background shell truncates it only once it has forked,
  # and a reused one could still show the last run's port.
  runs=$((runs + 1)); log="$tmp/edge$runs.log"
  "$edge" run --board "$board" --port 0 "$@" 2>"$log" &
  pid=$!
  i=0
  while ! grep -qs 'listening on port [0-9]' "$log"; do
    i=$((i + 1)); [ $i -gt 100 ] && { cat "$log"; echo "edge did not start"; exit 1; }
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
"$host" send "$data/defect_list.dml" --to "127.0.0.1:$port" >"$tmp/out"
grep -q '^ack job 42: 2 defects, sequence [0-9]*, digest [0-9a-f]\{64\} (matches)$' "$tmp/out" || { cat "$tmp/out"; exit 1; }
# A frame that is not a defect list is refused: exit 1, reason printed.
if "$host" send "$data/ack.dml" --to "127.0.0.1:$port" 2>"$tmp/err"; then echo "ack.dml accepted"; exit 1; fi
stop_edge
grep -q "job 42 panel 'door-FL-0001': 2 defects" "$log" || { cat "$log"; exit 1; }
grep -q 'shut down cleanly' "$log"

start_edge --key "$data/golden.key"
# Without the key: refused as unauthenticated.
if "$host" send "$data/defect_list.dml" --to "127.0.0.1:$port" 2>"$tmp/err"; then echo "unsigned accepted"; exit 1; fi
grep -q 'unauthenticated' "$tmp/err" || { cat "$tmp/err"; exit 1; }
"$host" send "$data/defect_list_signed.dml" --to "127.0.0.1:$port" --key "$data/golden.key" >"$tmp/out"
grep -q '(matches), authenticated$' "$tmp/out" || { cat "$tmp/out"; exit 1; }
stop_edge
echo "ok"
