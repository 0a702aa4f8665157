#!/usr/bin/env bash
# The flood measurement (docs/telemetry.md): does malformed UDP traffic toward the appliance
# change its RT loop? Runs the cbd scene in real time (the scene's SCHED_FIFO priority, CPU and
# mlock: run as root) with the telemetry stream on, ROUNDS times each without a flood, with a
# busy CPU and with a flood, alternating in one session, and prints one JSON line per run: overruns, wake-up latency and
# step time percentiles, frames sent and send errors, and the flood's own counters.
#
# Three kinds of run, in turn: quiet (a telemetry_dump receives the stream at 127.0.0.1:47850),
# busy (the same plus a busy loop pinned to the flood's CPU: the control, a CPU as loaded as
# the flood's but no network traffic) and flood. With a flood,
# udpflood is bound to that address (so its datagrams come from the telemetry destination and
# match the trainer's connected socket, the worst case for it) and floods the trainer's
# telemetry source port 47950 and ten other ports with malformed datagrams as fast as one CPU
# sends them, pinned to the CPU the RT loop does not use; it also receives and decodes the
# trainer's frames meanwhile.
#
# usage: tools/telemetry/flood_measure.sh [BUILD_DIR] [ROUNDS] [SECONDS]
# Needs the cbd images (modelc build --scene config/scenes/cbd.toml).
set -euo pipefail
source_dir=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$source_dir/build/release}
rounds=${2:-3}
seconds=${3:-20}
bin=$build/bin
scene=$source_dir/config/scenes/cbd.toml
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
rt_cpu=$(sed -n 's/^cpu *= *\([0-9]*\).*/\1/p' "$scene" | head -1)
flood_cpu=$(( rt_cpu == 0 ? 1 : 0 ))

run_once() {  # $1 = label (quiet|flood), $2 = round
  local label=$1 round=$2 helper_pid report=$work/$1_$2.json helper_out=$work/$1_$2_helper.json
  local burn_pid=
  if [ "$label" = busy ]; then
    taskset -c "$flood_cpu" timeout $((seconds + 3)) sh -c 'while :; do :; done' &
    burn_pid=$!
  fi
  if [ "$label" = flood ]; then
    "$bin/udpflood" --target 127.0.0.1 --ports 47950,47951-47960,22,53,80,443,5353 \
      --bind 127.0.0.1:47850 --rate 0 --seconds $((seconds + 3)) --cpu "$flood_cpu" \
      >"$helper_out" &
  else
    "$bin/telemetry_dump" --listen 127.0.0.1:47850 --seconds $((seconds + 3)) --idle-ms 60000 \
      >"$helper_out" &
  fi
  helper_pid=$!
  sleep 0.5
  "$bin/trainer" --scene "$scene" --hal sim --seconds "$seconds" \
    --telemetry 127.0.0.1:47850 --telemetry-source-port 47950 --report "$report" \
    >"$work/trainer.txt" 2>&1 || { cat "$work/trainer.txt"; exit 1; }
  wait "$helper_pid"
  if [ -n "$burn_pid" ]; then wait "$burn_pid" || true; fi
  python3 - "$label" "$round" "$report" "$helper_out" <<'PY'
import json, sys
label, round_, report, helper = sys.argv[1:]
r = json.load(open(report))
h = json.load(open(helper))

def us(p): return {k: round(v / 1000.0, 1) for k, v in p.items() if k in ("p50", "p99", "p99_9", "max")}
out = {
    "run": label, "round": int(round_), "cycles": r["cycles"],
    "overruns": r["overruns"], "longest_overrun_streak": r["longest_overrun_streak"],
    "wake_latency_us": us(r["wake_latency_ns"]), "step_time_us": us(r["step_time_ns"]),
    "policy": r["rt"]["policy"], "frames_sent": r["telemetry"]["frames_sent"],
    "send_errors": r["telemetry"]["send_errors"],
}
if label == "flood":
    out["flood"] = {k: h[k] for k in ("sent", "datagrams_per_s", "telemetry_frames_received")}
else:
    out["received"] = h["accepted"]
print(json.dumps(out))
PY
}

for round in $(seq "$rounds"); do
  run_once quiet "$round"
  run_once busy "$round"
  run_once flood "$round"
done
