#!/usr/bin/env bash
# Frame rate and end-to-end latency of the viewer in headless Chromium (docs/viewer.md): the
# viewer on loopback, a telemetry stream into it, the page kept open for SECONDS while it
# records, per drawn frame, the hops appliance cycle -> sent -> viewer received -> handed to the
# WebSocket -> page received -> on screen (the display refresh after the frame was rendered),
# all on CLOCK_REALTIME of this one machine. Prints the page's JSON figures and the viewer's
# summary (frame sizes, rebuild time).
#
#   tools/viewer/measure.sh [--build DIR] [--seconds S] [--reconstruct viewer|browser]
#                           [--rate HZ] [--scene FILE] [--trainer]
#   --trainer: the stream comes from the trainer running the scene on the simulated bench in
#              real time (trainer --telemetry 127.0.0.1:PORT --telemetry-rate RATE, rerun
#              while the measurement lasts); default: telemetry_test_sender (the wire library,
#              duct modes swinging), which measures the viewer and the page without the appliance.
set -euo pipefail
source_dir=$(cd "$(dirname "$0")/../.." && pwd)
build="$source_dir/build/release"
seconds=60
reconstruct=viewer
rate=60
scene="$source_dir/config/scenes/cbd.toml"
use_trainer=0
while [ $# -gt 0 ]; do
  case $1 in
    --build) build=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --reconstruct) reconstruct=$2; shift 2 ;;
    --rate) rate=$2; shift 2 ;;
    --scene) scene=$2; shift 2 ;;
    --trainer) use_trainer=1; shift ;;
    *) echo "measure.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
work=$(mktemp -d)
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; rm -rf "$work"; }
trap cleanup EXIT
"$build/bin/modelc" build --scene "$scene" >"$work/build.txt"
"$build/bin/viewer" --scene "$scene" --udp 127.0.0.1:${VIEWER_UDP_PORT:-0} --http-port 0 \
  --reconstruct "$reconstruct" --seconds $((seconds + 30)) >"$work/viewer.txt" 2>&1 &
viewer_pid=$!
pids+=("$viewer_pid")
for _ in $(seq 200); do grep -q "page at" "$work/viewer.txt" && break; sleep 0.05; done
http_port=$(sed -n 's|.*page at http://127.0.0.1:\([0-9]*\)/.*|\1|p' "$work/viewer.txt")
udp_port=$(sed -n 's|.*frames from udp 127.0.0.1:\([0-9]*\) .*|\1|p' "$work/viewer.txt")
if [ "$use_trainer" -eq 1 ]; then
  # The cbd script ends the run after ~11 s: the scene is rerun until the measurement is over.
  ( end=$((SECONDS + seconds + 20))
    while [ $SECONDS -lt $end ]; do
      "$build/bin/trainer" --scene "$scene" --hal sim --time real --no-rt \
        --telemetry "127.0.0.1:$udp_port" --telemetry-rate "$rate" >>"$work/sender.txt" 2>&1 \
        || sleep 0.2  # a run that latched a fault (overruns under load) exits 1: run the next
    done ) &
else
  "$build/tests/tools/viewer/telemetry_test_sender" "$scene" "$udp_port" $((seconds + 20)) "$rate" \
    >"$work/sender.txt" 2>&1 &
fi
pids+=("$!")
node "$source_dir/tests/tools/viewer/viewer_page.mjs" --modules "$build/tools/viewer/web/node_modules" \
  --url "http://127.0.0.1:$http_port/" --seconds "$seconds"
kill -TERM "$viewer_pid"
wait "$viewer_pid" || true
cat "$work/viewer.txt"
if [ "$use_trainer" -eq 1 ]; then
  echo "trainer runs: $(grep -c "^trainer: scene" "$work/sender.txt" || true)," \
       "with a latched fault: $(grep -c "first fault" "$work/sender.txt" || true)"
  grep -E "^  (overruns|telemetry:|safety:)" "$work/sender.txt" | sort | uniq -c | sort -rn | head -8
fi
