#!/bin/sh
# A trainer session recording opened by the reference MCAP reader (@mcap/core): records the wall
# scene for 3000 simulated cycles, then tests/rt/record/mcap_node/check.mjs reads it streaming
# (chunk CRCs) and indexed (summary, message indexes). The npm packages (package-lock.json) are
# installed once into the build tree; exit 77 (skipped) when node or the registry is missing.
# Usage: mcap_node_check.sh TRAINER SOURCE_DIR WORK_DIR
set -eu
trainer=$1
source_dir=$2
work=$3
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  echo "node/npm not installed: skipped"
  exit 77
fi
mkdir -p "$work"
if [ ! -f "$work/node_modules/@mcap/core/package.json" ] ||
   ! cmp -s "$source_dir/tests/rt/record/mcap_node/package-lock.json" "$work/package-lock.json"; then
  cp "$source_dir/tests/rt/record/mcap_node/package.json" \
     "$source_dir/tests/rt/record/mcap_node/package-lock.json" "$work/"
  if ! (cd "$work" && npm ci --no-audit --no-fund --loglevel=error); then
    echo "npm ci failed (no registry access?): skipped"
    exit 77
  fi
fi
cp "$source_dir/tests/rt/record/mcap_node/check.mjs" "$work/check.mjs"
recording="$work/wall.mcap"
rm -f "$recording"
"$trainer" --scene "$source_dir/config/scenes/wall.toml" --time simulated --cycles 3000 \
  --record "$recording" >/dev/null
node "$work/check.mjs" "$recording" 3000
