#!/usr/bin/env bash
# The viewer end to end in headless Chromium: the cbd scene's images built (modelc), the viewer
# started on loopback, a telemetry stream sent to it, and the page opened with puppeteer-core
# over the system's chromium (viewer_page.mjs): it must load the scene, connect, draw frames,
# and two screenshots 0.5 s apart must differ where the duct is; then the stream latches a fault
# and the page's banner must show it. Exit 77 (skip) without chromium. With SCREENSHOT, the page's screenshot is kept there (docs/img/viewer-cbd.png).
# usage: viewer_page_test.sh MODELC VIEWER SENDER NODE_MODULES SOURCE_DIR [SCREENSHOT]
#   SENDER: the telemetry_test_sender binary (frames encoded with the wire library)
set -euo pipefail
modelc=$1
viewer=$2
sender=$3
modules=$4
source_dir=$5
screenshot=${6:-}
chromium=${CHROMIUM:-/usr/bin/chromium}
[ -x "$chromium" ] || { echo "viewer_page_test: $chromium not found: skipped"; exit 77; }
work=$(mktemp -d)
viewer_pid=
sender_pid=
cleanup() {
  [ -n "$sender_pid" ] && kill "$sender_pid" 2>/dev/null || true
  [ -n "$viewer_pid" ] && kill "$viewer_pid" 2>/dev/null || true
  wait 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
cp -r "$source_dir/config" "$work/config"
scene="$work/config/scenes/cbd.toml"
"$modelc" build --scene "$scene" >"$work/build.txt" || { cat "$work/build.txt"; exit 1; }

"$viewer" --scene "$scene" --udp 127.0.0.1:0 --http-port 0 --seconds 30 >"$work/viewer.txt" 2>&1 &
viewer_pid=$!
for _ in $(seq 100); do grep -q "page at" "$work/viewer.txt" && break; sleep 0.05; done
grep -q "page at" "$work/viewer.txt" || { echo "viewer did not start"; cat "$work/viewer.txt"; exit 1; }
http_port=$(sed -n 's|.*page at http://127.0.0.1:\([0-9]*\)/.*|\1|p' "$work/viewer.txt")
udp_port=$(sed -n 's|.*frames from udp 127.0.0.1:\([0-9]*\) .*|\1|p' "$work/viewer.txt")
# Without a screenshot to keep, the stream latches a fault after 4 s: the banner must show it.
fault_after=${screenshot:+-1}
"$sender" "$scene" "$udp_port" 25 60 "${fault_after:-4}" >"$work/sender.txt" 2>&1 &
sender_pid=$!

status=0
node "$source_dir/tests/tools/viewer/viewer_page.mjs" --modules "$modules" --chromium "$chromium" \
  --url "http://127.0.0.1:$http_port/" ${screenshot:+--screenshot "$screenshot"} \
  ${screenshot:---expect-fault 10} || status=$?
kill "$sender_pid" 2>/dev/null || true
kill -TERM "$viewer_pid" 2>/dev/null || true
wait "$viewer_pid" 2>/dev/null || true
viewer_pid=
cat "$work/viewer.txt"
if [ "$status" -eq 0 ]; then
  grep -q '"malformed":0' "$work/viewer.txt" || { echo "viewer saw malformed datagrams"; status=1; }
fi
exit "$status"
