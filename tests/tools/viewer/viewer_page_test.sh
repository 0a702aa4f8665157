#!/usr/bin/env bash
# The viewer end to end in headless Chromium: the cbd scene's images built (modelc), the viewer
# started on loopback, a telemetry stream sent to it, and the page opened with puppeteer-core
# over the system's chromium (viewer_page.mjs). The page must load the scene, connect and draw,
# and two screenshots 0.5 s apart must differ where the duct is; with the trainer's stream the
# session panel must show the trainee metrics the frames carry. Then a stream latching a fault
# must bring up the page's red banner. Exit 77 (skip) without chromium.
#
# SENDER is either the trainer (the real appliance stream: the cbd scene on the simulated bench
# in real time with --telemetry to the viewer; the duct must really deform, by >= 0.3 mm; then
# `trainer --no-arm` for the fault) or telemetry_test_sender (frames encoded with the wire
# library; it latches a fault after 4 s).
# With SCREENSHOT, the page is kept there at cycle 6000 (trainer: the catheter in the duct,
# the right forceps on it), for docs/img/viewer-cbd.png.
# usage: viewer_page_test.sh MODELC VIEWER SENDER NODE_MODULES SOURCE_DIR [SCREENSHOT]
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

"$viewer" --scene "$scene" --udp 127.0.0.1:0 --http-port 0 --seconds 40 >"$work/viewer.txt" 2>&1 &
viewer_pid=$!
for _ in $(seq 100); do grep -q "page at" "$work/viewer.txt" && break; sleep 0.05; done
grep -q "page at" "$work/viewer.txt" || { echo "viewer did not start"; cat "$work/viewer.txt"; exit 1; }
http_port=$(sed -n 's|.*page at http://127.0.0.1:\([0-9]*\)/.*|\1|p' "$work/viewer.txt")
udp_port=$(sed -n 's|.*frames from udp 127.0.0.1:\([0-9]*\) .*|\1|p' "$work/viewer.txt")

checks=()
if [ "$(basename "$sender")" = trainer ]; then
  "$sender" --scene "$scene" --hal sim --time real --no-rt --telemetry "127.0.0.1:$udp_port" \
    --report "$work/run.json" >"$work/sender.txt" 2>&1 &
  sender_pid=$!
  checks+=(--attempts 16 --expect-deformation 0.0003 --expect-metrics 5)
  [ -n "$screenshot" ] && checks+=(--screenshot-cycle 6000)
  fault="'$sender' --scene '$scene' --hal sim --time real --no-rt --no-arm --seconds 4 \
--telemetry 127.0.0.1:$udp_port >'$work/fault.txt' 2>&1"
  checks+=(--fault-command "kill $sender_pid 2>/dev/null; $fault" --expect-fault 10)
else
  fault_after=4
  [ -n "$screenshot" ] && fault_after=-1
  "$sender" "$scene" "$udp_port" 25 60 "$fault_after" >"$work/sender.txt" 2>&1 &
  sender_pid=$!
  [ -z "$screenshot" ] && checks+=(--expect-fault 10)
fi

status=0
node "$source_dir/tests/tools/viewer/viewer_page.mjs" --modules "$modules" --chromium "$chromium" \
  --url "http://127.0.0.1:$http_port/" ${screenshot:+--screenshot "$screenshot"} "${checks[@]}" \
  || status=$?
kill "$sender_pid" 2>/dev/null || true
kill -TERM "$viewer_pid" 2>/dev/null || true
wait "$viewer_pid" 2>/dev/null || true
viewer_pid=
cat "$work/viewer.txt"
if [ "$status" -eq 0 ]; then
  grep -q '"malformed":0' "$work/viewer.txt" || { echo "viewer saw malformed datagrams"; status=1; }
fi
exit "$status"
