#!/usr/bin/env bash
# Writes the seed corpus of fuzz_model_image (tests/fuzz/corpus/fuzz_model_image/): model images
# built by modelc from the repository's own model definitions, each behind the target's control
# byte 0 (kind from the header, checksum recomputed by the harness). Checked-in images must stay
# small (the repository stays lean; libFuzzer's -max_len is 16384), so the duct and the liver are
# the repository's definitions (config/models/duct.toml, liver.toml) with their meshes coarsened
# and fewer modes; the catheters are the repository's own (config/models/catheter.toml,
# catheter_cbd.toml: 21 and 41 particles, ~0.5-1 KiB) built as they are.
#   tests/fuzz/make_image_seeds.sh [MODELC]   (default build/release/bin/modelc)
set -euo pipefail
cd "$(dirname "$0")/../.."
modelc=${1:-build/release/bin/modelc}
out=tests/fuzz/corpus/fuzz_model_image
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/config/models" "$work/config/scenes" "$work/out/models"
cp config/devices -r "$work/config/"
cp config/trajectories -r "$work/config/"

# coarsen FILE KEY=VALUE...: the repository's definition with some keys replaced.
coarsen() {
  local source=$1 target=$2
  shift 2
  cp "$source" "$target"
  local pair
  for pair in "$@"; do
    sed -i -E "s|^${pair%%=*} *=.*|${pair%%=*} = ${pair#*=}|" "$target"
  done
}
coarsen config/models/duct.toml "$work/config/models/duct.toml" rings=3 segments=6 mode_count=4
coarsen config/models/duct.toml "$work/config/models/duct_nosc.toml" rings=3 segments=5 mode_count=3 \
  static_correction=false 'image="../../out/models/duct_nosc.img"' 'name="duct_nosc"'
coarsen config/models/liver.toml "$work/config/models/liver.toml" 'divisions=[2, 2, 1]'
coarsen config/models/liver.toml "$work/config/models/liver_linear.toml" 'divisions=[1, 2, 1]' \
  'image="../../out/models/liver_linear.img"' 'name="liver_linear"'
# the linear variant drops the [nonlinear.*] tables (identity maps)
sed -i '/^\[nonlinear/,$d' "$work/config/models/liver_linear.toml"
cp config/models/catheter.toml config/models/catheter_cbd.toml "$work/config/models/"

# A scene holds at most 4 models: two scenes of three.
scene() {
  local file=$work/config/scenes/$1.toml
  shift
  cat >"$file" <<TOML
[scene]
name = "seeds"
device = "../devices/sim.toml"
[loop]
period_us = 1000
[safety]
max_force_n = 8.0
max_force_rate_n_per_s = 4000.0
max_joint_speed_rad_per_s = 20.0
max_insertion_speed_m_per_s = 1.0
passivity_energy_bound_j = 0.5
require_enable_input = false
[[instrument]]
name = "left"
device_instrument = "left"
TOML
  local model
  for model in "$@"; do
    printf '[[model]]\nname = "%s"\ndefinition = "../models/%s.toml"\n' "$model" "$model" >>"$file"
  done
  "$modelc" build --scene "$file" >/dev/null
}
scene shells duct duct_nosc catheter
scene solids liver liver_linear catheter_cbd

rm -rf "$out"
mkdir -p "$out"
for image in "$work"/out/models/*.img; do
  name=$(basename "$image" .img)
  { printf '\0'; cat "$image"; } >"$out/$name"
done
ls -l "$out"
