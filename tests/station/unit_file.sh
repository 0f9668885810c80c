#!/usr/bin/env bash
# The daemon's systemd unit: systemd itself checks it (syntax, directives, the command
# it starts) and rates its sandboxing. Usage: unit_file.sh UNIT DENTMARK_EDGE_BINARY
set -euo pipefail
unit="$1" binary="$2"
command -v systemd-analyze >/dev/null || { echo "SKIP: systemd-analyze not installed"; exit 77; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The unit names the installed path; point it at this build's binary.
sed "s#/usr/bin/dentmark-edge#$binary#" "$unit" >"$work/dentmark-edge.service"
grep -q '^Type=notify$' "$work/dentmark-edge.service"
grep -q '^WatchdogSec=' "$work/dentmark-edge.service"
grep -q '^StateDirectory=dentmark$' "$work/dentmark-edge.service"
systemd-analyze verify --man=no "$work/dentmark-edge.service"
exposure=$(systemd-analyze security --offline=yes "$work/dentmark-edge.service" | sed -n 's/.*Overall exposure level for [^:]*: \([0-9.]*\).*/\1/p')
echo "exposure level $exposure (0 = fully sandboxed, 10 = not at all)"
awk -v e="$exposure" 'BEGIN { exit !(e != "" && e <= 3.0) }'
