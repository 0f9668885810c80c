#!/bin/bash
# V4l2Camera.StreamsFromAKernelDevice (tests/hal/test_camera.cpp) on vivid, the
# kernel's virtual video test driver, loaded with one video-capture node only. A skip
# here is a failure: the device exists.
# Usage (in the guest): v4l2_vivid.sh <source dir> <build dir>
set -u
build="$2"
modprobe vivid n_devs=1 node_types=0x1 || exit 1
dev=""
for n in /sys/class/video4linux/video*; do
  [[ -r "$n/name" && "$(cat "$n/name")" == vivid-000-vid-cap ]] && dev="/dev/${n##*/}"
done
if [[ -z "$dev" ]]; then
  echo "fail: vivid is loaded but has no vivid-000-vid-cap node"
  exit 1
fi
echo "vivid capture node: $dev"
out="$(DENTMARK_V4L2_DEVICE="$dev" "$build/tests/hal/test_camera" \
  --gtest_filter=V4l2Camera.StreamsFromAKernelDevice 2>&1)"
rc=$?
echo "$out"
if grep -q '\[  SKIPPED \]' <<<"$out"; then
  echo "fail: the test skipped although $dev exists"
  exit 1
fi
grep -q '\[  PASSED  \] 1 test' <<<"$out" || exit 1
exit "$rc"
