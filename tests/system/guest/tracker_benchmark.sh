#!/bin/bash
# host: bench-sequence
# The aarch64 tracker benchmark (tests/track/bench_track.cpp, Google Benchmark) in the
# guest: per stereo frame of 1280x1024, tracking and the start from seeds. Emulated by
# TCG, so the figures are not the target's, only proof that the path runs. The
# sequence (`dentmark synth stereo --seconds 3`, the one the benchmark renders itself
# elsewhere) is rendered on the host and passed in DENTMARK_BENCH_SEQUENCE.
# Usage (in the guest): tracker_benchmark.sh <source dir> <build dir>
set -u
build="$2"
if [[ -z "${DENTMARK_BENCH_SEQUENCE:-}" ]]; then
  echo "skip: no DENTMARK_BENCH_SEQUENCE (the harness found no host dentmark CLI)"
  exit 77
fi
out="$("$build/tests/track/bench_track" --benchmark_filter='BM_(TrackStereoFrame|StartFromSeeds)1280x1024' \
  --benchmark_min_time=1 2>&1)"
rc=$?
echo "$out"
[[ $rc -eq 0 ]] || exit 1
# Both benchmarks ran and tracking kept its 10 features.
grep -qE '^BM_TrackStereoFrame1280x1024 +[0-9.]+ ms .*features=10' <<<"$out" || exit 1
grep -qE '^BM_StartFromSeeds1280x1024 +[0-9.]+ ms' <<<"$out" || exit 1
