#!/usr/bin/env bash
# The forceps tip pressing the modal duct through the whole cycle: the wall scene's trainee
# script (insert, hold, slide sideways, withdraw) with the wall removed and the default duct
# placed across the left tool's path 3 mm above its deepest reach. The duct's surface is
# rebuilt and bucketed while the tool is near, the touched material point follows the tip
# (displacement-driven modal contact) and the tool feels the solved force: finite, bounded,
# zero heap after arming, no faults, the duct back at rest afterwards (no step errors).
# usage: duct_press_test.sh MODELC TRAINER SOURCE_DIR
set -euo pipefail
modelc=$1
trainer=$2
source_dir=$3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp -r "$source_dir/config" "$work/config"
python3 - "$work/config/scenes" <<'PY'
import sys
scenes = sys.argv[1]
src = open(f"{scenes}/duct.toml").read()
start, end = src.index("[[object]]"), src.index("[[model]]")
src = src[:start] + src[end:]
# Duct axis along x through (-0.0622, 0, -0.1063): the left tip (x = -0.05) meets its top
# (z = -0.102) at mid-length; the script inserts to 0.105 m, 3 mm further.
src = src.replace('definition = "../models/duct.toml"',
                  'definition = "../models/duct.toml"\nposition_m = [-0.0622, 0.0, -0.1063]')
open(f"{scenes}/duct_press.toml", "w").write(src)
PY
scene="$work/config/scenes/duct_press.toml"
"$modelc" build --scene "$scene" >"$work/build.txt"
"$trainer" --scene "$scene" --hal sim --time simulated --report "$work/run.json" >"$work/run.txt" 2>&1 \
  || { echo "trainer failed"; cat "$work/run.txt"; exit 1; }
python3 - "$work/run.json" <<'PY'
import json, sys
run = json.load(open(sys.argv[1]))
left = run["instruments"][0]
assert run["memory"]["heap_allocations_after_arming"] == 0, run["memory"]
assert run["safety"]["faults_latched_at_end"] == 0, run["safety"]
assert run["model_step_errors"] == 0, run["model_step_errors"]
assert left["contact_cycles"] > 1000, left
# A 3 mm press (plus the sideways slide) on a 0.3 MPa duct: tenths of a newton to about a
# newton, far below the scene's 8 N limit; zero would mean no contact, above it a blow-up.
assert 0.05 < left["peak_force_n"] < 3.0, left
assert run["models"][0]["position_m"] == [-0.0622, 0.0, -0.1063], run["models"][0]
# The trainee metrics: every cycle sampled, the press on the duct counted as force on tissue
# (the scene's tissue is the duct: what the tip felt of it is at most the commanded force).
m = run["metrics"]
assert m["samples"] == run["cycles"] and m["refused_samples"] == 0, m
mi = m["instruments"][0]
assert mi["contact_time_s"] > 1.0 and 0.05 < mi["peak_force_n"] <= left["peak_force_n"] + 1e-3, (mi, left)
print(f"duct press: {left['contact_cycles']} contact cycles, peak {left['peak_force_n']:.3f} N, "
      f"mean {left['mean_contact_force_n']:.3f} N, no heap, no faults")
PY
