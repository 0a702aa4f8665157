#!/usr/bin/env bash
# Files an appliance trusts (docs/fuzzing.md): the trainer binary refuses a damaged model image
# (a flipped byte, a truncated file), a malformed device file and a malformed scene before
# arming: exit status 1, a message naming the file, and no report (the report is written only
# after a run). The catheter scene is used because its image builds in milliseconds.
# usage: untrusted_files_test.sh MODELC TRAINER SOURCE_DIR
set -euo pipefail
modelc=$1
trainer=$2
source_dir=$3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cp -r "$source_dir/config" "$work/config"
scene="$work/config/scenes/catheter.toml"
image="$work/out/models/catheter.img"
"$modelc" build --scene "$scene" >"$work/build.txt"
test -s "$image" || { echo "no image written"; cat "$work/build.txt"; exit 1; }
cp "$image" "$work/good.img"

# expect_refusal NAME TEXT... -- TRAINER ARGS: exit 1, every TEXT in the output, no report.
expect_refusal() {
  local name=$1
  shift
  local texts=()
  while [ "$1" != "--" ]; do texts+=("$1"); shift; done
  shift
  local status=0
  rm -f "$work/run.json"
  "$trainer" "$@" --hal sim --time simulated --cycles 10 --report "$work/run.json" \
    >"$work/$name.txt" 2>&1 || status=$?
  if [ "$status" -ne 1 ]; then echo "$name: exit $status, expected 1"; cat "$work/$name.txt"; exit 1; fi
  local text
  for text in "${texts[@]}"; do
    grep -qF -- "$text" "$work/$name.txt" || { echo "$name: no '$text' in:"; cat "$work/$name.txt"; exit 1; }
  done
  if [ -e "$work/run.json" ]; then echo "$name: a report was written: it ran"; exit 1; fi
  echo "$name refused: $(head -c 240 "$work/$name.txt")"
}

python3 - "$image" <<'PY'
import sys
path = sys.argv[1]
data = bytearray(open(path, "rb").read())
data[len(data) // 2] ^= 0x01
open(path, "wb").write(bytes(data))
PY
expect_refusal flipped_byte "catheter.img" "checksum" -- --scene "$scene"
head -c -1 "$work/good.img" >"$image"
expect_refusal truncated "catheter.img" "file_bytes" -- --scene "$scene"
cp "$work/good.img" "$image"

sed 's/^\[device\]/[device/' "$work/config/devices/sim.toml" >"$work/config/devices/broken.toml"
expect_refusal broken_device "broken.toml:" "syntax error" -- --scene "$scene" \
  --device "$work/config/devices/broken.toml"
sed 's/^period_us = 1000/period_us = 0/' "$scene" >"$work/config/scenes/broken.toml"
expect_refusal broken_scene "broken.toml:" "period_us" -- --scene "$work/config/scenes/broken.toml"

# The good files run (what was refused above were the edits).
"$trainer" --scene "$scene" --hal sim --time simulated --cycles 10 --report "$work/run.json" \
  >"$work/good.txt" 2>&1 || { echo "the good scene failed"; cat "$work/good.txt"; exit 1; }
test -s "$work/run.json" || { echo "no report from the good run"; exit 1; }
echo "good scene ran 10 cycles"
