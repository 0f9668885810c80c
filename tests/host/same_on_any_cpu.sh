#!/usr/bin/env bash
# Detection's hot loops have an x86-64-v3 (AVX2) clone beside the baseline one, picked
# when the program starts (host/detect/hot_loop.h). A scan must give the same findings,
# to the last digit, on either: this runs the command natively and under qemu-x86_64
# emulating a CPU without AVX (Nehalem), and compares the JSON outputs but their timing.
# Skips (exit 77) without qemu-x86_64 or without AVX2 here (both runs would be baseline).
#   same_on_any_cpu.sh DENTMARK SCAN OUTDIR
set -euo pipefail
dentmark=$1 scan=$2 out=$3
command -v qemu-x86_64 >/dev/null || { echo "skipped: no qemu-x86_64"; exit 77; }
grep -qw avx2 /proc/cpuinfo || { echo "skipped: this CPU has no AVX2"; exit 77; }
mkdir -p "$out"
"$dentmark" detect "$scan" --out "$out/v3.dml" --json "$out/v3.json" >/dev/null
qemu-x86_64 -cpu Nehalem "$dentmark" detect "$scan" --out "$out/baseline.dml" --json "$out/baseline.json" >/dev/null
findings() { sed '/"timing": {/,/}/d' "$1"; }
if ! diff <(findings "$out/v3.json") <(findings "$out/baseline.json"); then
  echo "FAIL: the AVX2 and baseline loops disagree on $scan"
  exit 1
fi
echo "same findings on AVX2 and baseline x86-64: $(grep -c '"class"' "$out/v3.json") classified regions"
