#!/bin/bash
# Makes the booted guest an edge box for the station tests (docs/system-tests.md,
# "The station"), once per boot: the daemon's package files installed from the shared
# tree (unit, sysusers, udev rule; the binary from the aarch64 build), the board file
# of boards/qemu/virt-aarch64-guest, a calibration folder, a gpio-sim chip with the
# board's label and line names, two vivid instances looping their HDMI output back to
# their capture, fed the rendered door by tests/system/tools/vivid_feeder. Then
# (re)starts dentmark-edge under systemd and waits for READY=1.
#   setup.sh SOURCE BUILD STATE ROBOT_PORT [--restart]
# STATE (in the build tree, shared with the host) holds the rendered sequence (seq/)
# and the libraries the guest image lacks (lib/). Writes /run/dentmark-station/env
# (the gpio-sim paths) for the other station scripts.
set -u
src="$1" build="$2" state="$3" robot_port="$4"
restart="${5:-}"
run=/run/dentmark-station
fail() {
  echo "station setup: $*"
  exit 1
}
t0=$EPOCHREALTIME
elapsed() { echo "$EPOCHREALTIME $t0" | awk '{printf "%.1f", $1 - $2}'; }

if [[ ! -f $run/env ]]; then
  board_src="$src/boards/qemu/virt-aarch64-guest/board.yaml"
  line_of() { sed -n "s/^  $1: { line: \"\([^\"]*\)\".*/\1/p" "$board_src"; }
  label=$(sed -n 's/^  chip_label: "\([^"]*\)".*/\1/p' "$board_src")
  valve=$(line_of sprayer_valve) estop=$(line_of estop) part=$(line_of part_present)
  [[ -n "$label" && -n "$valve" && -n "$estop" && -n "$part" ]] || fail "$board_src: no chip label or line names"

  # Libraries the aarch64 build links that the guest image lacks (the harness copies
  # them from the arm64 sysroot the build linked against).
  if compgen -G "$state/lib/*.so*" >/dev/null; then
    cp "$state"/lib/*.so* /usr/local/lib/ && ldconfig || fail "installing $state/lib"
  fi

  # The package's files, as a Debian package would install them.
  install -D -m644 "$src/packaging/sysusers/dentmark-edge.conf" /usr/lib/sysusers.d/dentmark-edge.conf &&
    systemd-sysusers /usr/lib/sysusers.d/dentmark-edge.conf &&
    install -D -m644 "$src/packaging/udev/60-dentmark-gpio.rules" /etc/udev/rules.d/60-dentmark-gpio.rules &&
    udevadm control --reload &&
    udevadm trigger --subsystem-match=gpio --action=add && # the chips that exist already, as a postinst does
    install -D -m644 "$src/packaging/systemd/dentmark-edge.service" /etc/systemd/system/dentmark-edge.service &&
    ln -sfn "$build/firmware/app/dentmark-edge" /usr/bin/dentmark-edge || fail "installing the package files"
  id dentmark || fail "no dentmark user after systemd-sysusers"

  # GPIO: a gpio-sim chip with the board's label and lines; e-stop released (its line
  # is active low: pulled up), a part present.
  modprobe gpio-sim || fail "modprobe gpio-sim"
  mountpoint -q /sys/kernel/config || mount -t configfs configfs /sys/kernel/config || fail "configfs"
  cfg=/sys/kernel/config/gpio-sim/dentmark-station
  mkdir "$cfg" "$cfg/bank0" && echo "$label" >"$cfg/bank0/label" && echo 3 >"$cfg/bank0/num_lines" || fail "gpio-sim chip"
  names=("$valve" "$estop" "$part")
  for i in 0 1 2; do
    mkdir "$cfg/bank0/line$i" && echo "${names[$i]}" >"$cfg/bank0/line$i/name" || fail "gpio-sim line $i"
  done
  echo 1 >"$cfg/live" || fail "gpio-sim: live"
  udevadm settle
  chip=$(cat "$cfg/bank0/chip_name") dev=$(cat "$cfg/dev_name")
  sim="/sys/devices/platform/$dev/$chip"
  echo pull-up >"$sim/sim_gpio1/pull" && echo pull-up >"$sim/sim_gpio2/pull" || fail "gpio-sim pulls"
  echo "gpio: $chip '$label' ($dev): ${names[*]}; $(stat -c '%G %a' /dev/$chip)"

  # Cameras: vivid with HDMI in and out only, no crop/compose/scaler, 640x480p59.94
  # (DV timings index 0) on both ends, the output looped back to the capture, no
  # on-screen text.
  rmmod vivid 2>/dev/null
  modprobe vivid n_devs=2 node_types=0x101,0x101 num_inputs=1,1 input_types=0x3,0x3 num_outputs=1,1 \
    output_types=0x1,0x1 ccs_cap_mode=0,0 ccs_out_mode=0,0 vid_cap_nr=10,11 vid_out_nr=12,13 || fail "modprobe vivid"
  udevadm settle
  for d in 10 11; do
    v4l2-ctl -d /dev/video$d --set-dv-bt-timings index=0 -c loop_video=1,osd_text_mode=2 >/dev/null ||
      fail "/dev/video$d: timings and loop"
  done
  for d in 12 13; do
    v4l2-ctl -d /dev/video$d --set-dv-bt-timings index=0 >/dev/null || fail "/dev/video$d: timings"
  done
  v4l2-ctl -d /dev/video10 -V | grep -q 'Width/Height *: 640/480' || fail "vivid capture is not 640x480"

  # Calibration: the rendered rig, identity robot and scanner transforms, the door's
  # panel model taught on the sequence's first frame.
  cal=/etc/dentmark/calibration
  mkdir -p "$cal/models" && cp "$state/seq/stereo.yaml" "$cal/stereo.yaml" || fail "calibration folder"
  for t in robot:T_base_camL scanner:T_camL_sls; do
    printf '%%YAML:1.0\n---\n%s: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1. ]\nrms: 0.\n' \
      "${t#*:}" >"$cal/${t%%:*}.yaml"
  done
  dentmark-edge teach --sequence "$state/seq" --out "$cal/models/door-FL-0001.yaml" 2>&1 | tail -1
  [[ -s "$cal/models/door-FL-0001.yaml" ]] || fail "teaching the panel model"
  # The board file, with the port the host's robot simulator listens on.
  sed "s/^  port: 1502$/  port: $robot_port/" "$board_src" >/etc/dentmark/board.yaml
  grep -q "port: $robot_port" /etc/dentmark/board.yaml || fail "board file: robot port"

  # Time limits for an emulated CPU (the unit reads its extra arguments from this
  # file): the valve watchdog at 3 s instead of 0.2 s (the job's control loop missed
  # 1 s while the host did not run the emulator; the e-stop path does not depend on
  # it); 60 s instead of 5 s for the tracker to find the door and catch up on the kept
  # pairs, and estimates up to 2 s old instead of 0.5 s (a 640x480 pair takes the
  # emulated tracker a large fraction of a second).
  echo 'DENTMARK_EDGE_ARGS=--watchdog-timeout 3.0 --tracking-timeout 60 --max-estimate-age 2' \
    >/etc/default/dentmark-edge
  # The one drop-in: starting (dynamic linking, the calibration, the cameras) took the
  # emulated CPU over the unit's 60 s on a loaded host, and systemd killed the daemon
  # just as it sent READY=1.
  mkdir -p /etc/systemd/system/dentmark-edge.service.d
  printf '[Service]\nTimeoutStartSec=300s\n' >/etc/systemd/system/dentmark-edge.service.d/emulated-cpu.conf

  # The rendered door into the vivid outputs.
  systemd-run --quiet --unit=dentmark-feeder "$build/tests/system/vivid_feeder" "$state/seq" /dev/video12 \
    /dev/video13 || fail "starting the feeder"
  for _ in $(seq 600); do
    journalctl -u dentmark-feeder -o cat | grep -q '^streaming' && break
    systemctl is-active -q dentmark-feeder || break
    sleep 0.5
  done
  journalctl -u dentmark-feeder -o cat | grep -E '^(loaded|streaming)' || fail "the feeder is not streaming: $(journalctl -u dentmark-feeder -o cat | tail -3)"

  mkdir -p $run
  cat >$run/env <<EOF
VALVE_VALUE=$sim/sim_gpio0/value
ESTOP_PULL=$sim/sim_gpio1/pull
ESTOP_PRESSED=pull-down
ESTOP_RELEASED=pull-up
EOF
  systemctl daemon-reload
  echo "station set up in $(elapsed) s"
  restart=--restart
fi

if [[ "$restart" == --restart ]] || ! systemctl is-active -q dentmark-edge; then
  t1=$EPOCHREALTIME
  # Type=notify: 'start' returns once the daemon sent READY=1 (or failed).
  systemctl restart dentmark-edge
  rc=$?
  ready=$(echo "$EPOCHREALTIME $t1" | awk '{printf "%.1f", $1 - $2}')
  if [[ $rc -ne 0 ]]; then
    systemctl status --no-pager dentmark-edge | tail -20
    fail "dentmark-edge did not start"
  fi
  echo "dentmark-edge: READY=1 ${ready} s after 'systemctl restart'"
fi
systemctl show -p ActiveState,SubState,Type,NRestarts,StatusText dentmark-edge
