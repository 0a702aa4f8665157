#!/usr/bin/env bash
# Every injected drive fault over vcan0 in the bench VM (can_faults.sh), judged by
# check_faults.py: latched within the stated cycles, zero force from then on.
#   can_faults_test.sh SOURCE_DIR BIN_DIR [OUT_DIR]
set -euo pipefail
src=$1 bin=$2
work=${3:-$(mktemp -d)}
[ $# -ge 3 ] || trap 'rm -rf "$work"' EXIT
mkdir -p "$work"
cd "$src"
status=0
tools/benchvm/benchvm run --smp 2 --timeout 600 --out "$work" -- \
  tests/benchvm/can_faults.sh "$bin" 16 || status=$?
[ "$status" -ne 77 ] || exit 77
[ "$status" -eq 0 ] || { echo "FAIL: the fault sessions exited with $status"; exit 1; }
python3 tests/benchvm/check_faults.py "$work"
