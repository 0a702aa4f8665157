#!/usr/bin/env bash
# hil against simdrive over vcan0 in the bench VM (hil_can_bench.py: good | miswired | trials).
#   hil_can_test.sh SOURCE_DIR BIN_DIR MODE [TRIALS] [OUT_DIR]
# Runs from the source directory so that the guest (host root read-only, its own /tmp) finds
# the scripts and the device files by relative path.
set -euo pipefail
src=$1 bin=$2 mode=$3 trials=${4:-3}
work=${5:-$(mktemp -d)}
[ $# -ge 5 ] || trap 'rm -rf "$work"' EXIT
mkdir -p "$work"
cd "$src"
exec tools/benchvm/benchvm run --smp 2 --timeout 600 --out "$work" -- \
  python3 tests/benchvm/hil_can_bench.py "$bin" "$work" "$mode" "$trials"
