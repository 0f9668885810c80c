#!/bin/sh
# `dentmark-edge selftest` against a loopback station (loopback_station.sh): it passes
# when every device answers, and each broken piece fails its own check by name with the
# others still run: robot simulator gone, calibration file missing, calibration marked
# bad by `calibrate verify`, calibration for
# other cameras, board file broken (device checks skipped), state folder not a folder.
#   selftest.sh DENTMARK_EDGE DENTMARK
set -eu
edge=$1 host=$2
tmp=$(mktemp -d)
robot=
cleanup() {
  [ -n "$robot" ] && kill -9 "$robot" 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT
. "$(dirname "$0")/loopback_station.sh"
loopback_station "$tmp" 2

fail() { echo "FAIL: $*"; exit 1; }
# selftest NAME EXPECTED_EXIT [BOARD [STATE_DIR]]: runs it, output in $tmp/NAME.out
selftest() {
  name=$1 want=$2 board=${3:-$tmp/board.yaml} state=${4:-$tmp/state}
  rc=0
  "$edge" selftest --board "$board" --calibration "$tmp/cal" --state-dir "$state" >"$tmp/$name.out" 2>&1 || rc=$?
  echo "--- $name (exit $rc)"; cat "$tmp/$name.out"
  [ "$rc" -eq "$want" ] || fail "$name: exit $rc, expected $want"
}
expect() { grep -q "$2" "$tmp/$1.out" || fail "$1: no line '$2'"; }

selftest healthy 0
for check in board calibration gpio robot "camera left" "camera right" state; do expect healthy "^ok   $check: "; done
expect healthy "^ok   robot: reachable"
expect healthy "^ok   camera left: .*frame 640x512"
[ "$(grep -c '^ok ' "$tmp/healthy.out")" -eq 7 ] || fail "healthy: not 7 checks passed"

mv "$tmp/cal/stereo.yaml" "$tmp/stereo.yaml"
selftest no_stereo 1
expect no_stereo "^FAIL calibration: .*stereo.yaml"
expect no_stereo "^ok   robot: "
mv "$tmp/stereo.yaml" "$tmp/cal/stereo.yaml"

echo "calibrate verify: point transfer RMS 5.1 mm > tolerance 2.0 mm" >"$tmp/cal/calibration.bad"
selftest calibration_bad 1
expect calibration_bad "^FAIL calibration: .*calibration.bad: the stored calibration is known bad (calibrate verify: point"
rm "$tmp/cal/calibration.bad"

sed 's/width: 640, height: 512/width: 1280, height: 1024/' "$tmp/board.yaml" >"$tmp/big.yaml"
selftest big 1 "$tmp/big.yaml"
expect big "^FAIL calibration: .*calibrated for 640x512, the board's cameras give 1280x1024"
expect big "^FAIL camera left: .*frames are 640x512, the board says 1280x1024"

printf 'board: { vendor: test\n' >"$tmp/broken.yaml"
selftest broken 1 "$tmp/broken.yaml"
expect broken "^FAIL board: .*broken.yaml"
expect broken "^skip robot: no valid board file"
expect broken "^ok   state: "

touch "$tmp/state-file"
selftest state_file 1 "$tmp/board.yaml" "$tmp/state-file"
expect state_file "^FAIL state: .*state-file"

kill -9 "$robot"; wait "$robot" 2>/dev/null || true; robot=
selftest no_robot 1
expect no_robot "^FAIL robot: .*127.0.0.1"
expect no_robot "^ok   camera right: "
expect no_robot "^self-test FAILED"
echo "selftest: all cases behaved"
