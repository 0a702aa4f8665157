#!/usr/bin/env bash
# End to end for Cotin's tensor model: `modelc build --scene` precomputes the liver-sized block
# (config/models/liver.toml, 1,989 nodes) and checks the float32 runtime against a direct solve;
# the trainer runs the liver scene's scripted probe to its end (press, drag, second press) with
# the configured quasi-non-linear maps and no heap after arming, and again with the maps removed:
# the non-linear run's peak force must be the force map applied to the linear run's stiffness at
# the non-linear run's indentation. A decreasing polynomial map and a corrupted image are each
# refused before arming, naming the file.
# usage: liver_pipeline_test.sh MODELC TRAINER SOURCE_DIR
set -euo pipefail
modelc=$1
trainer=$2
source_dir=$3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cp -r "$source_dir/config" "$work/config"
scene="$work/config/scenes/liver.toml"
image="$work/out/models/liver.img"

"$modelc" build --scene "$scene" --report "$work/build.json" >"$work/build.txt"
test -s "$image" || { echo "no image written"; cat "$work/build.txt"; exit 1; }

"$trainer" --scene "$scene" --hal sim --time simulated --report "$work/run.json" \
  >"$work/run.txt" 2>&1 || { echo "trainer failed"; cat "$work/run.txt"; exit 1; }
# The same scene with the linear model: the [nonlinear.*] tables removed from a copy.
cp -r "$work/config" "$work/linear"
python3 - "$work/linear/models/liver.toml" <<'PY'
import sys
path = sys.argv[1]
text = open(path).read()
open(path, "w").write(text[:text.index("[nonlinear.")])  # the image path still leads to $work/out
PY
"$trainer" --scene "$work/linear/scenes/liver.toml" --hal sim --time simulated \
  --report "$work/linear.json" >"$work/linear.txt" 2>&1 || { echo "linear run failed"; cat "$work/linear.txt"; exit 1; }
python3 - "$work/build.json" "$work/run.json" "$work/linear.json" <<'PY'
import json, math, sys
build = json.load(open(sys.argv[1]))
run = json.load(open(sys.argv[2]))
linear = json.load(open(sys.argv[3]))
model = build["models"][0]
assert model["kind"] == "tet_tensor" and model["node_count"] == 1989, model
assert model["contact_node_count"] > 500, model
# The float32 tensors reproduce the direct double-precision solve (1, 2 and 8 contacts):
# float rounding is 6e-8; 1e-5 of the largest value leaves room for conditioning.
checks = model["agreement_with_direct_solve"]
assert [c["contacts"] for c in checks] == [1, 2, 8], checks
for c in checks:
    assert c["displacement_error"] < 1e-5 and c["force_error"] < 1e-5, c
assert model["self_tensor_error"] < 1e-9, model
assert model["timings_s"]["total"] < 120, "precompute should take seconds"
assert run["memory"]["heap_allocations_after_arming"] == 0, run["memory"]
loaded = run["models"][0]
assert loaded["kind"] == "tet_tensor" and loaded["quasi_nonlinear"] is True, loaded
assert loaded["image_bytes"] == model["image_bytes"] and loaded["max_contacts"] == 8, loaded
assert run["safety"]["faults_latched_at_end"] == 0, run["safety"]
assert run["model_step_errors"] == 0, run["model_step_errors"]

# The probe: two presses (a drag may let go and touch again), every force finite and below the
# safety limit (8 N) without being clamped by it, the contact released at the end.
load = loaded["load"]
for r in (run, linear):
    assert r["memory"]["heap_allocations_after_arming"] == 0, r["memory"]
    assert r["safety"]["faults_latched_at_end"] == 0, r["safety"]
    p = r["instruments"][0]
    assert 2 <= p["contact_onsets"] <= 4, p
    assert 3000 < p["contact_cycles"] < r["cycles"] - 1000, (p, r["cycles"])
    assert math.isfinite(p["peak_force_n"]) and 1.0 < p["peak_force_n"] < 7.9, p
    l = r["models"][0]["load"]
    assert l["peak_contact_nodes"] == 3 and l["refused_solves"] == 0, l
    # What the tissue took is what the probe felt (action = reaction, no clamp).
    assert abs(l["peak_force_n"] - p["peak_force_n"]) < 1e-3 * p["peak_force_n"], (l, p)
    assert abs(l["peak_indentation_m"] - p["peak_depth_m"]) < 1e-9, (l, p)
    # The trainee metrics: the probe's force on the liver is the force it felt (nothing else
    # touches it), its contact time the contact cycles times the period.
    m = r["metrics"]
    assert m["samples"] == r["cycles"] and m["refused_samples"] == 0, m
    mi = m["instruments"][0]
    assert abs(mi["peak_force_n"] - p["peak_force_n"]) < 1e-3 * p["peak_force_n"], (mi, p)
    assert abs(mi["contact_time_s"] - p["contact_cycles"] * r["period_ns"] * 1e-9) < 1e-6, (mi, p)
assert run["cycles"] == linear["cycles"] >= 15000, (run["cycles"], linear["cycles"])
# Quasi-non-linear (Cotin §4.3): the colinear force map P(a) = a + 0.5 a^2 + 0.1 a^3 (N) on the
# linear force. The linear run gives the block's stiffness under the probe; at the non-linear
# run's peak indentation the linear force is that stiffness times it, and the felt peak force
# must be P of it (both peaks are at the second, deepest press, nearly normal to the face).
linear_load = linear["models"][0]["load"]
stiffness = linear_load["peak_force_n"] / linear_load["peak_indentation_m"]
a = stiffness * load["peak_indentation_m"]
expected = a + 0.5 * a * a + 0.1 * a ** 3
assert abs(load["peak_force_n"] - expected) < 0.05 * expected, (load, expected, stiffness)
assert load["peak_indentation_m"] < linear_load["peak_indentation_m"], "stiffening must indent less"
print(f"probe: linear {linear_load['peak_force_n']:.2f} N at {1e3 * linear_load['peak_indentation_m']:.2f} mm "
      f"({stiffness:.0f} N/m); quasi-non-linear {load['peak_force_n']:.2f} N at "
      f"{1e3 * load['peak_indentation_m']:.2f} mm, predicted {expected:.2f} N")
print(f"built {model['node_count']} nodes in {model['timings_s']['total']:.2f} s, image "
      f"{model['image_bytes']} bytes, worst agreement "
      f"{max(c['displacement_error'] for c in checks):.2e}; trainer loaded it, no heap")
PY

# A polynomial map that decreases inside its range is refused at start, naming the map.
definition="$work/config/models/liver.toml"
cp "$definition" "$work/liver.toml.good"
sed -i 's/coefficients = \[0.0, 1.0, 0.5, 0.1\]/coefficients = [0.0, 1.0, -0.5]/' "$definition"
status=0
"$trainer" --scene "$scene" --hal sim --time simulated --cycles 10 >"$work/bad_map.txt" 2>&1 || status=$?
if [ "$status" -ne 1 ]; then echo "bad map: exit $status, expected 1"; cat "$work/bad_map.txt"; exit 1; fi
grep -q "nonlinear.force_colinear" "$work/bad_map.txt" || { echo "message does not name the map"; cat "$work/bad_map.txt"; exit 1; }
grep -q "decreases" "$work/bad_map.txt" || { echo "message does not say why"; cat "$work/bad_map.txt"; exit 1; }
cp "$work/liver.toml.good" "$definition"

# One flipped byte: the checksum refuses the image before arming.
python3 - "$image" <<'PY'
import sys
path = sys.argv[1]
data = bytearray(open(path, "rb").read())
data[len(data) // 2] ^= 0x40
open(path, "wb").write(bytes(data))
PY
status=0
"$trainer" --scene "$scene" --hal sim --time simulated --cycles 10 >"$work/bad.txt" 2>&1 || status=$?
if [ "$status" -ne 1 ]; then echo "corrupt image: exit $status, expected 1"; cat "$work/bad.txt"; exit 1; fi
grep -q "liver.img" "$work/bad.txt" || { echo "message does not name the image"; cat "$work/bad.txt"; exit 1; }
grep -qi "checksum" "$work/bad.txt" || { echo "message does not name the checksum"; cat "$work/bad.txt"; exit 1; }
echo "bad map and corrupt image refused"
