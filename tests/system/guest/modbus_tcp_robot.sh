#!/bin/bash
# host: robot-sim
# ModbusRobot in the guest against `dentmark robot-sim` on the host, over QEMU's
# user-mode network (tests/hal/modbus_remote_robot.cpp). The harness starts the
# simulator (the line above asks for it) and passes its address as seen from the
# guest in DENTMARK_ROBOT (10.0.2.2:<port>).
# Usage (in the guest): modbus_tcp_robot.sh <source dir> <build dir>
set -u
build="$2"
if [[ -z "${DENTMARK_ROBOT:-}" ]]; then
  echo "skip: no DENTMARK_ROBOT (the harness found no host dentmark CLI)"
  exit 77
fi
exec "$build/tests/hal/modbus_remote_robot" "$DENTMARK_ROBOT"
