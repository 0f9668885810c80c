#!/bin/bash
# libcamera_capture (tests/hal/libcamera_capture.cpp) through libcamera's vimc
# pipeline handler on vimc, the kernel's virtual media controller (sensor -> debayer
# -> scaler -> capture), built out of tree by tests/system/guest-image.
# Usage (in the guest): libcamera_vimc.sh <source dir> <build dir>
set -u
build="$2"
modprobe vimc || exit 1
export LIBCAMERA_LOG_LEVELS="*:ERROR"
# libcamera 0.0.3 vimc pipeline narrows 640x480 to 636x480; 960x720 it keeps.
exec "$build/tests/hal/libcamera_capture" 960x720
