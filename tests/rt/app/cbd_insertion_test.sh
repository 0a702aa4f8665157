#!/usr/bin/env bash
# The reference scene end to end (config/scenes/cbd.toml): modelc builds the duct image, the
# trainer runs the scripted procedure on the simulated bench in simulated time, and the JSON
# report must show: the run ended with the script, zero heap allocations after arming, no
# fault (a non-finite force or effort latches one), no model step error, the left forceps
# grasped the catheter once without it slipping, the catheter's tip reached the target depth
# in the duct, the duct was loaded by the right forceps and by the catheter, and every force
# and effort stayed finite and within the scene's safety limit and the actuators' range.
# usage: cbd_insertion_test.sh MODELC TRAINER SOURCE_DIR
set -euo pipefail
modelc=$1
trainer=$2
source_dir=$3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp -r "$source_dir/config" "$work/config"
scene="$work/config/scenes/cbd.toml"
"$modelc" build --scene "$scene" >"$work/build.txt"
"$trainer" --scene "$scene" --hal sim --time simulated --report "$work/run.json" >"$work/run.txt" 2>&1 \
  || { echo "trainer failed"; cat "$work/run.txt"; exit 1; }
python3 - "$work/run.json" <<'PY'
import json, math, sys
run = json.load(open(sys.argv[1]))
assert run["memory"]["heap_allocations_after_arming"] == 0, run["memory"]
assert run["safety"]["faults_latched_at_end"] == 0, run["safety"]
assert run["model_step_errors"] == 0, run["model_step_errors"]
left, right = run["instruments"]
duct = next(m for m in run["models"] if m["name"] == "duct")
catheter = next(m for m in run["models"] if m["name"] == "catheter")
# The procedure: one grasp, held to the end of the carry (no slip), the target depth reached.
assert left["catheter"]["grasps"] == 1, left["catheter"]
assert left["catheter"]["slips"] == 0, left["catheter"]
assert left["catheter"]["peak_squeeze_n"] > 0.5, left["catheter"]
insertion = catheter["insertion"]
assert insertion["target_reached"], insertion
assert insertion["peak_depth_m"] >= insertion["target_depth_m"], insertion
# Inside the 24.4 mm duct while the jaws push it; released, the bent catheter straightens and
# may run on (it is free), but never farther than its own length.
assert insertion["target_depth_m"] <= insertion["peak_held_depth_m"] < 0.0244, insertion
assert insertion["peak_depth_m"] < 0.15, insertion
# The duct felt both the right forceps (steadying press) and the catheter inside it.
load = duct["load"]
assert load["tool_contact_cycles"] > 1000, load
assert load["catheter_contact_cycles"] > 0, load
assert 0.05 < load["peak_force_n"] < 3.0, load
# Forces and efforts: finite (else a fault latched) and within the 8 N limit with margin.
limit = 8.0
for tool in (left, right):
    assert math.isfinite(tool["peak_force_n"]) and tool["peak_force_n"] < limit, tool
    for name, value in tool["peak_joint_effort"].items():
        assert math.isfinite(value), (name, tool)
assert right["contact_cycles"] > 1000, right
# The right forceps rests on the duct with its jaws as well as its tip (ray-based contact).
assert right["wall_segment_contact_cycles"] > 100, right
# The trainee metrics (docs/metrics.md) in the report, from every cycle's record, agree with
# the report's own statistics: one grasp without a slip, the target reached at the depth the
# catheter's statistics give, both forceps moved.
m = run["metrics"]
assert m["samples"] == run["cycles"] and m["refused_samples"] == 0 and m["dropped_cycles"] == 0, m
assert m["task"]["completed"] and m["insertion"]["target_reached"], m["task"]
assert abs(m["insertion"]["max_depth_m"] - insertion["peak_depth_m"]) < 1e-6, (m["insertion"], insertion)
assert 0 < m["insertion"]["time_to_target_s"] < run["cycles"] * run["period_ns"] * 1e-9, m["insertion"]
ml, mr = m["instruments"]
assert ml["name"] == "left" and ml["grasps"] == left["catheter"]["grasps"] and ml["slips"] == 0, ml
assert ml["path_length_m"] > 0.03 and mr["path_length_m"] > 0.03, (ml, mr)
assert 0 < mr["peak_force_n"] <= right["peak_force_n"] + 1e-3, (mr, right)
print(f"cbd insertion: peak depth {insertion['peak_depth_m'] * 1e3:.1f} mm (target "
      f"{insertion['target_depth_m'] * 1e3:.0f} mm), squeeze {left['catheter']['peak_squeeze_n']:.2f} N, "
      f"duct peak {load['peak_force_n']:.3f} N mean {load['mean_force_n']:.3f} N, "
      f"left peak {left['peak_force_n']:.3f} N, right peak {right['peak_force_n']:.3f} N, no heap, no faults")
PY

# Issue 19's measurement: the sub-stages of the modal and catheter stages in the report (one
# sample per cycle each; a stage's mean holds its sub-stages' means), and a short --repeat run
# whose per-cycle minima keep the same order (step >= its stages >= their sub-stages).
"$trainer" --scene "$scene" --hal sim --time simulated --repeat 2 --cycles 3000 \
  --report "$work/repeat.json" >"$work/repeat.txt" 2>&1 \
  || { echo "trainer --repeat failed"; cat "$work/repeat.txt"; exit 1; }
python3 - "$work/run.json" "$work/repeat.json" <<'PY'
import json, sys
run = json.load(open(sys.argv[1]))
repeat = json.load(open(sys.argv[2]))
modal = ["modal_near", "modal_collision", "modal_solve", "modal_step", "modal_reconstruct", "modal_refit"]
catheter = ["catheter_walls", "catheter_tools", "catheter_step", "catheter_reactions"]
sub = run["step_substages_ns"]
assert set(sub) == set(modal + catheter), sub
for name in modal + catheter:
    assert sub[name]["count"] == run["cycles"], (name, sub[name])
split = run["step_split_ns"]
for stage, names in (("modal_models", modal), ("catheters", catheter)):
    assert split[stage]["mean"] >= sum(sub[n]["mean"] for n in names), (stage, split[stage], sub)
    assert sub[names[0]]["mean"] > 0, sub
assert run["step_time_ns"]["mean"] >= sum(s["mean"] for s in split.values()), (run["step_time_ns"], split)
c = repeat["compute"]
assert c["runs"] == 2 and c["cycles"] == 3000 and c["identical"], c
assert set(c["substages_ns"]) == set(modal + catheter), c["substages_ns"]
assert c["step_ns"]["mean"] >= sum(s["mean"] for s in c["stages_ns"].values()), c
for stage, names in (("modal_models", modal), ("catheters", catheter)):
    assert c["stages_ns"][stage]["mean"] >= sum(c["substages_ns"][n]["mean"] for n in names), (stage, c)
assert repeat["memory"]["heap_allocations_after_arming"] == 0, repeat["memory"]
print(f"cbd compute: step per-cycle minimum p50 {c['step_ns']['p50'] / 1e3:.1f} us over 2 x 3000 cycles")
PY
