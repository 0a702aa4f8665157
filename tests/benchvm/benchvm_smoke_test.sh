#!/usr/bin/env bash
# The bench VM's smoke tests (tools/benchvm/benchvm, docs/bench-vm.md).
#   benchvm_smoke_test.sh vcan SOURCE_DIR
#       boots the VM and runs guest_checks.sh inside: PREEMPT_RT kernel, read-only host root,
#       vcan0 up, candump receives cansend's frame, error frames enabled on a raw socket, a
#       frame between raw sockets and through cangw; checks the file it writes to the out
#       directory from the host. The guest command ends with exit 42 once the checks passed:
#       the guest command's status reaches the host (one boot for both).
# Exits 77 (skip) when benchvm does: QEMU cannot run here, or no kernel can be had.
set -euo pipefail
mode=$1
src=$2
benchvm=$src/tools/benchvm/benchvm
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

status=0
case "$mode" in
  vcan)
    cd "$src"
    "$benchvm" run --timeout 90 --out "$work" -- \
      sh -c 'tests/benchvm/guest_checks.sh && exit 42' || status=$?
    [ "$status" -ne 77 ] || exit 77
    [ "$status" -eq 42 ] || { echo "FAIL: benchvm run exited with $status, not the guest's 42"; exit 1; }
    grep -q '^all checks passed in .*-rt-' "$work/guest-checks.txt" \
      || { echo "FAIL: $work/guest-checks.txt missing or wrong"; exit 1; }
    echo "PASS: $(cat "$work/guest-checks.txt"); the guest's exit status 42 reached the host"
    ;;
  *)
    echo "usage: benchvm_smoke_test.sh vcan SOURCE_DIR" >&2
    exit 2
    ;;
esac
