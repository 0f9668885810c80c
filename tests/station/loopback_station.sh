# Sourced by the daemon's process tests: a station on this machine's loopback, for
# `dentmark-edge run` as a process. Simulated GPIO lines; cameras replaying a rendered
# sequence of the door (its panel model taught as door-FL-0001); identity robot and
# scanner transforms; the robot simulator as its own process over Modbus TCP.
#   loopback_station DIR SECONDS [ROBOT_SIM_OPTIONS...]
# needs $edge and $host (the two binaries); sets $robot (the simulator's pid) and
# writes DIR/board.yaml and DIR/cal/.
wait_for() {  # file pattern what
  i=0
  while ! grep -qs "$2" "$1"; do
    i=$((i + 1)); [ $i -gt 600 ] && { cat "$1"; echo "timed out waiting for $3"; exit 1; }
    sleep 0.1
  done
}

loopback_station() {
  dir=$1 seconds=$2
  shift 2
  "$host" synth stereo --out "$dir/seq" --seconds "$seconds" --width 640 --height 512 --focal 870 >/dev/null 2>&1
  mkdir -p "$dir/cal/models"
  cp "$dir/seq/stereo.yaml" "$dir/cal/stereo.yaml"
  "$edge" teach --sequence "$dir/seq" --out "$dir/cal/models/door-FL-0001.yaml" 2>/dev/null
  for t in robot:T_base_camL scanner:T_camL_sls; do
    printf '%%YAML:1.0\n---\n%s: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1. ]\nrms: 0.\n' \
      "${t#*:}" >"$dir/cal/${t%%:*}.yaml"
  done
  "$host" robot-sim --port 0 "$@" >"$dir/robot.log" 2>&1 &
  robot=$!
  wait_for "$dir/robot.log" 'listening on [0-9.]*:[0-9]' "the robot simulator"
  robot_port=$(sed -n 's/.*listening on [0-9.]*:\([0-9][0-9]*\).*/\1/p' "$dir/robot.log" | head -1)
  # The limits are the robot simulator's own workspace.
  cat >"$dir/board.yaml" <<YAML
board: { vendor: test, name: loopback }
cpu: { arch: x86_64 }
gpio:
  backend: sim
  sprayer_valve: { line: "sprayer-valve" }
  estop: { line: "estop", active_low: true }
camera: { backend: replay, left: "$dir/seq", width: 640, height: 512 }
modbus: { transport: tcp, host: "127.0.0.1", port: $robot_port, timeout: 0.5 }
link: { port: 7878 }
limits: { workspace_min: [-0.6, -0.8, -0.1], workspace_max: [0.9, 0.8, 1.2], max_speed: 0.25, max_acceleration: 1.0 }
YAML
}
