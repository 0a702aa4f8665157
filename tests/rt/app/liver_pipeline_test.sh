#!/usr/bin/env bash
# End to end for Cotin's tensor model: `modelc build --scene` precomputes the liver-sized block
# (config/models/liver.toml, 1,989 nodes) and checks the float32 runtime against a direct solve;
# the trainer loads the image, creates the model with the configured quasi-non-linear maps, and
# runs with no heap after arming; a decreasing polynomial map and a corrupted image are each
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

"$trainer" --scene "$scene" --hal sim --time simulated --cycles 5000 --report "$work/run.json" \
  >"$work/run.txt" 2>&1 || { echo "trainer failed"; cat "$work/run.txt"; exit 1; }
python3 - "$work/build.json" "$work/run.json" <<'PY'
import json, sys
build = json.load(open(sys.argv[1]))
run = json.load(open(sys.argv[2]))
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
