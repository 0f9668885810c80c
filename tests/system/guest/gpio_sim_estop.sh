#!/bin/bash
# E-stop edge -> valve low through the GPIO character device on a gpio-sim chip made
# from the board file (tests/hal/gpio_sim_estop.cpp); gpio-sim is the out-of-tree
# module of tests/system/guest-image. 50 trials, each within 10 ms.
# Usage (in the guest): gpio_sim_estop.sh <source dir> <build dir>
set -u
src="$1" build="$2"
modprobe gpio-sim || exit 1
mountpoint -q /sys/kernel/config || mount -t configfs configfs /sys/kernel/config || exit 1
exec "$build/tests/hal/gpio_sim_estop" "$src/boards/qemu/virt-aarch64-guest/board.yaml" 50
