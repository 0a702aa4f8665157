#!/usr/bin/env bash
# A few kill trials in the bench VM (can_kill_trials.py; the 100-trial distribution comes from
# tools/benchvm/can-kill-trials): every drive must remove torque by itself within its heartbeat
# consumer time after the trainer is SIGKILLed.
#   can_kill_trials_test.sh SOURCE_DIR BIN_DIR TRIALS
# Runs from the source directory so that the guest, which sees the host root read-only but
# its own tmpfs on /tmp, finds the scripts and files by relative path.
set -euo pipefail
src=$1 bin=$2 trials=$3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$src"
exec tools/benchvm/benchvm run --smp 2 --timeout 300 --out "$work" -- \
  python3 tests/benchvm/can_kill_trials.py "$bin" config/scenes/wall.toml \
  config/devices/canopen_vcan.toml "$trials" "$work/kill_trials.json" 8
