#!/usr/bin/env bash
# trainer --repeat through the binary (issue 19): refused with exit 2 and a message in real
# time, with a recording, out of range; a repeated wall run writes the compute section (per
# runs, identical, per-cycle minima no larger than each run's own), its summary lines and the
# per-cycle CSV (--compute-csv).
# usage: trainer_repeat_test.sh TRAINER_BINARY SCENE_FILE
set -euo pipefail
trainer=$1
scene=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

expect_usage_error() {
  local expected=$1
  shift
  local status=0
  "$trainer" --scene "$scene" --hal sim --no-rt "$@" >"$work/out.txt" 2>&1 || status=$?
  if [ "$status" -ne 2 ] || ! grep -q -- "$expected" "$work/out.txt"; then
    echo "trainer $* : expected exit 2 with '$expected', got $status:"; cat "$work/out.txt"; exit 1
  fi
}
expect_usage_error "--repeat needs --time simulated" --repeat 2 --cycles 10
expect_usage_error "cannot record" --time simulated --repeat 2 --cycles 10 --record "$work/x.mcap"
expect_usage_error "cannot record" --time simulated --repeat 2 --cycles 10 --report-dir "$work/reports"
expect_usage_error "--repeat" --time simulated --repeat 0 --cycles 10
expect_usage_error "--repeat" --time simulated --repeat 101 --cycles 10
[ ! -e "$work/x.mcap" ] || { echo "a refused run wrote its recording"; exit 1; }

"$trainer" --scene "$scene" --hal sim --time simulated --repeat 2 --cycles 300 \
  --report "$work/repeat.json" --compute-csv "$work/minima.csv" >"$work/repeat.txt" 2>&1 \
  || { echo "repeated run failed"; cat "$work/repeat.txt"; exit 1; }
grep -q "compute, per-cycle minimum of 2 run(s) of 300 cycles" "$work/repeat.txt" \
  || { echo "no compute lines in the summary"; cat "$work/repeat.txt"; exit 1; }
python3 - "$work/repeat.json" "$work/minima.csv" <<'PY'
import csv, json, sys
report = json.load(open(sys.argv[1]))
rows = list(csv.DictReader(open(sys.argv[2])))
assert len(rows) == 300 and rows[-1]["cycle"] == "299", len(rows)
assert max(int(r["step"]) for r in rows) == report["compute"]["step_ns"]["max"], rows[:3]
c = report["compute"]
assert c["runs"] == 2 and c["cycles"] == 300 and c["identical"], c
assert c["period_ns"] == report["period_ns"], c
assert len(c["per_run"]) == 2 and c["per_run"][0]["final_state_hash"] == c["per_run"][1]["final_state_hash"], c
for run in c["per_run"]:
    assert c["step_ns"]["p50"] <= run["step_ns"]["p50"] and c["step_ns"]["max"] <= run["step_ns"]["max"], (c, run)
assert 0 < c["step_ns"]["min"] <= c["step_ns"]["p50"] <= c["step_ns"]["p99_9"] <= c["step_ns"]["max"], c
assert c["step_ns"]["mean"] >= sum(s["mean"] for s in c["stages_ns"].values()), c
assert set(c["stages_ns"]) == {"hal_read", "kinematics", "forces", "hal_write", "publish"}, c
assert c["substages_ns"] == {}, c
# Simulated time: the step time is real-clock now (it read 0 before issue 19).
assert report["step_time_ns"]["min"] > 0, report["step_time_ns"]
assert report["memory"]["heap_allocations_after_arming"] == 0, report["memory"]
print("repeat: 2 identical runs, step per-cycle minimum p50", c["step_ns"]["p50"], "ns")
PY
