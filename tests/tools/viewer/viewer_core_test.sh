#!/usr/bin/env bash
# Builds the cbd scene's images (modelc, ~0.5 s) in a temporary copy of config/ and runs the
# viewer's core tests on them, then the page's JavaScript rebuild against the C++ one. usage: viewer_core_test.sh MODELC TEST_BINARY SOURCE_DIR
set -euo pipefail
modelc=$1
binary=$2
source_dir=$3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp -r "$source_dir/config" "$work/config"
"$modelc" build --scene "$work/config/scenes/cbd.toml" >"$work/build.txt" \
  || { cat "$work/build.txt"; exit 1; }
mkdir "$work/fixture"
VIEWER_TEST_SCENE="$work/config/scenes/cbd.toml" VIEWER_TEST_JS_FIXTURE="$work/fixture" "$binary"
# The page's rebuild (browser placement) against the C++ one, when node is there.
if command -v node >/dev/null 2>&1; then
  node "$source_dir/tests/tools/viewer/check_browser_rebuild.mjs" "$source_dir" "$work/fixture"
fi
