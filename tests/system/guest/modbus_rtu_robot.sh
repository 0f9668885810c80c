#!/bin/bash
# host: robot-sim-rtu
# ModbusRobot in the guest over RTU against `dentmark robot-sim --rtu` on the host:
# the guest's second UART (a 16550 on PCI, 8250_pci) is a QEMU chardev on one end of
# a pty pair whose other end the simulator opens (the line above asks the harness
# for it). tests/hal/modbus_remote_robot.cpp, 115200 8N1.
# Usage (in the guest): modbus_rtu_robot.sh <source dir> <build dir>
set -u
build="$2"
tty=""
for t in /sys/class/tty/ttyS*; do
  # The PCI UART is the one with a device behind it on the PCI bus.
  if [[ "$(readlink -f "$t/device/subsystem" 2>/dev/null)" == */bus/pci ]]; then
    tty="/dev/${t##*/}"
    break
  fi
done
if [[ -z "$tty" ]]; then
  echo "fail: no PCI UART (ttyS*) in the guest"
  exit 1
fi
echo "second UART: $tty"
exec "$build/tests/hal/modbus_remote_robot" "rtu:$tty"
