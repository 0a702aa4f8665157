#!/usr/bin/env bash
# The viewer's playback of a session recording in headless Chromium: the cbd scene's images
# built (modelc), a cbd session recorded by the trainer (simulated time, 8000 cycles: the right
# forceps press the duct from cycle ~2990), the viewer started with --source recording, the page
# opened (viewer_page.mjs --playback-seek): the playback bar shows, pause holds the frame, and
# a seek from 1 s (before any contact) to 7.5 s (the duct pressed) changes the duct's screen area.
# Exit 77 (skip) without chromium.
# usage: viewer_playback_test.sh MODELC VIEWER TRAINER NODE_MODULES SOURCE_DIR
set -euo pipefail
modelc=$1
viewer=$2
trainer=$3
modules=$4
source_dir=$5
chromium=${CHROMIUM:-/usr/bin/chromium}
[ -x "$chromium" ] || { echo "viewer_playback_test: $chromium not found: skipped"; exit 77; }
work=$(mktemp -d)
viewer_pid=
cleanup() {
  [ -n "$viewer_pid" ] && kill "$viewer_pid" 2>/dev/null || true
  wait 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
cp -r "$source_dir/config" "$work/config"
scene="$work/config/scenes/cbd.toml"
"$modelc" build --scene "$scene" >"$work/build.txt" || { cat "$work/build.txt"; exit 1; }
"$trainer" --scene "$scene" --hal sim --time simulated --no-rt --cycles 8000 \
  --record "$work/cbd.mcap" --report "$work/run.json" >"$work/trainer.txt" 2>&1 \
  || { cat "$work/trainer.txt"; exit 1; }

"$viewer" --scene "$scene" --source recording --recording "$work/cbd.mcap" --http-port 0 \
  --seconds 30 >"$work/viewer.txt" 2>&1 &
viewer_pid=$!
for _ in $(seq 100); do grep -q "page at" "$work/viewer.txt" && break; sleep 0.05; done
grep -q "page at" "$work/viewer.txt" || { echo "viewer did not start"; cat "$work/viewer.txt"; exit 1; }
http_port=$(sed -n 's|.*page at http://127.0.0.1:\([0-9]*\)/.*|\1|p' "$work/viewer.txt")

status=0
node "$source_dir/tests/tools/viewer/viewer_page.mjs" --modules "$modules" --chromium "$chromium" \
  --url "http://127.0.0.1:$http_port/" --playback-seek 1,7.5 || status=$?
kill -TERM "$viewer_pid" 2>/dev/null || true
wait "$viewer_pid" 2>/dev/null || true
viewer_pid=
cat "$work/viewer.txt"
exit "$status"
