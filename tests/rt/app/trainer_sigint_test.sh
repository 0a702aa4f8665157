#!/usr/bin/env bash
# End to end: the trainer binary, stopped by SIGINT (and SIGTERM) mid-run, zeroes and disables
# its outputs, exits cleanly and still writes its report.
# usage: trainer_sigint_test.sh TRAINER_BINARY SCENE_FILE
set -euo pipefail
trainer=$1
scene=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

for signal in INT TERM; do
  report="$work/report-$signal.json"
  "$trainer" --scene "$scene" --hal sim --seconds 60 --no-rt --report "$report" \
    >"$work/out-$signal.txt" 2>&1 &
  pid=$!
  sleep 1
  kill -s "$signal" "$pid"
  status=0
  wait "$pid" || status=$?
  if [ "$status" -ne 0 ]; then
    echo "SIG$signal: trainer exited with $status"; cat "$work/out-$signal.txt"; exit 1
  fi
  python3 - "$report" "$signal" <<'PY'
import json, sys
report = json.load(open(sys.argv[1]))
signal = sys.argv[2]
assert report["stopped_by_signal"] is True, f"SIG{signal}: stopped_by_signal is false"
assert report["safety"]["outputs_zeroed_at_exit"] is True, f"SIG{signal}: outputs not zeroed"
assert 0 < report["cycles"] < report["requested_cycles"], f"SIG{signal}: cycles {report['cycles']}"
assert report["memory"]["heap_allocations_after_arming"] == 0, f"SIG{signal}: heap used"
print(f"SIG{signal}: stopped after {report['cycles']} cycles, outputs zeroed, report written")
PY
done
