#!/usr/bin/env bash
# Builds the cbd scene's images (modelc, ~0.5 s) in a temporary copy of config/ and runs the
# viewer's core tests on them. usage: viewer_core_test.sh MODELC TEST_BINARY SOURCE_DIR
set -euo pipefail
modelc=$1
binary=$2
source_dir=$3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp -r "$source_dir/config" "$work/config"
"$modelc" build --scene "$work/config/scenes/cbd.toml" >"$work/build.txt" \
  || { cat "$work/build.txt"; exit 1; }
VIEWER_TEST_SCENE="$work/config/scenes/cbd.toml" "$binary"
