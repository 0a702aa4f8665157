#!/usr/bin/env bash
# End to end, offline to appliance: `modelc build --scene` writes the duct image a scene names,
# the trainer loads it into its arena and steps it every cycle with no heap after arming, and a
# corrupted image is refused before arming with a message naming the file and the remedy.
# usage: duct_pipeline_test.sh MODELC TRAINER SOURCE_DIR
set -euo pipefail
modelc=$1
trainer=$2
source_dir=$3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# A private copy of config/, so the image lands in $work/out (the model file says ../../out).
cp -r "$source_dir/config" "$work/config"
scene="$work/config/scenes/duct.toml"
image="$work/out/models/duct.img"

"$modelc" build --scene "$scene" --report "$work/build.json" >"$work/build.txt"
test -s "$image" || { echo "no image written"; cat "$work/build.txt"; exit 1; }

"$trainer" --scene "$scene" --hal sim --time simulated --cycles 20000 --report "$work/run.json" \
  >"$work/run.txt" 2>&1 || { echo "trainer failed"; cat "$work/run.txt"; exit 1; }
python3 - "$work/build.json" "$work/run.json" <<'PY'
import json, sys
build = json.load(open(sys.argv[1]))
run = json.load(open(sys.argv[2]))
model = build["models"][0]
assert model["name"] == "duct" and model["mode_count"] == 40 and model["node_count"] == 336, model
assert model["timings_s"]["total"] < 30, "precompute should take seconds"
assert run["cycles"] == 20000, run["cycles"]
assert run["memory"]["heap_allocations_after_arming"] == 0, run["memory"]
loaded = run["models"][0]
assert loaded["name"] == "duct" and loaded["mode_count"] == 40, loaded
assert loaded["image_bytes"] == model["image_bytes"], (loaded, model)
assert run["model_step_errors"] == 0
assert run["safety"]["faults_latched_at_end"] == 0, run["safety"]
assert run["memory"]["arena_bytes_used"] > loaded["image_bytes"], run["memory"]
print(f"built {model['mode_count']} modes in {model['timings_s']['total']:.2f} s; "
      f"trainer ran 20000 cycles with the duct, arena {run['memory']['arena_bytes_used']} bytes, no heap")
PY

# Flip one byte in the payload: the checksum must refuse the image before arming.
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
grep -q "duct.img" "$work/bad.txt" || { echo "message does not name the image"; cat "$work/bad.txt"; exit 1; }
grep -qi "checksum" "$work/bad.txt" || { echo "message does not name the checksum"; cat "$work/bad.txt"; exit 1; }
grep -q "modelc build" "$work/bad.txt" || { echo "message does not give the remedy"; cat "$work/bad.txt"; exit 1; }
echo "corrupt image refused: $(head -c 300 "$work/bad.txt")"
