#!/usr/bin/env bash
# The telemetry stream end to end on loopback (docs/telemetry.md): modelc builds the cbd
# images, telemetry_dump listens on a port the kernel picks, the trainer runs the cbd scene on
# the simulated bench in simulated time with --telemetry to that port, and the receiver's
# summary must show: every frame decoded (none refused), the images' checksums matched, sequence
# numbers rising with nothing lost (loopback), the final frame flagged, every frame ≤ 1 KiB,
# as many frames as the trainer's report says it sent, and the final frame's catheter tip where
# the report puts it.
# usage: telemetry_stream_test.sh MODELC TRAINER TELEMETRY_DUMP SOURCE_DIR
set -euo pipefail
modelc=$1
trainer=$2
dump=$3
source_dir=$4
work=$(mktemp -d)
dump_pid=
trap '[ -n "$dump_pid" ] && kill "$dump_pid" 2>/dev/null; rm -rf "$work"' EXIT
cp -r "$source_dir/config" "$work/config"
scene="$work/config/scenes/cbd.toml"
"$modelc" build --scene "$scene" >"$work/build.txt"
"$dump" --listen 127.0.0.1:0 --port-file "$work/port" --idle-ms 3000 --seconds 60 \
  --image "$work/out/models/duct.img" --image "$work/out/models/catheter_cbd.img" \
  >"$work/summary.json" &
dump_pid=$!
for _ in $(seq 100); do [ -s "$work/port" ] && break; sleep 0.05; done
port=$(cat "$work/port")
"$trainer" --scene "$scene" --hal sim --time simulated --telemetry "127.0.0.1:$port" \
  --report "$work/run.json" >"$work/run.txt" 2>&1 || { echo "trainer failed"; cat "$work/run.txt"; exit 1; }
wait "$dump_pid"
dump_pid=
python3 - "$work/summary.json" "$work/run.json" <<'PY'
import json, sys
summary = json.load(open(sys.argv[1]))
run = json.load(open(sys.argv[2]))
sent = run["telemetry"]
print("receiver:", json.dumps({k: summary[k] for k in ("datagrams", "accepted", "lost", "frame_bytes", "max_loads", "max_contacts")}))
print("sender:", json.dumps({k: sent[k] for k in ("frames_sent", "send_errors", "frame_bytes")}))
assert summary["refused"] == {}, summary["refused"]
assert summary["images_checked"] == 2 and summary["model_mismatch"] == 0, summary
assert summary["sequence_increasing"] and summary["lost"] == 0, summary
assert summary["duplicates"] == 0 and summary["late"] == 0, summary
assert summary["run_ended"], "no final frame"
assert summary["accepted"] >= 10, summary["accepted"]
assert summary["accepted"] == sent["frames_sent"] and sent["send_errors"] == 0, (summary, sent)
assert summary["frame_bytes"]["max"] <= 1024, summary["frame_bytes"]
assert sent["frame_bytes"]["max"] == summary["frame_bytes"]["max"], (sent, summary)
last = summary["last"]
kinds = [m["kind"] for m in last["models"]]
assert kinds == ["modal", "catheter"], kinds
duct, catheter = last["models"]
assert duct["modes"] == 40 and duct["static_correction"], duct
assert catheter["particles"] == 11, catheter
tip = next(m for m in run["models"] if m["name"] == "catheter")["final_tip_position_m"]
assert all(abs(a - b) < 1e-6 for a, b in zip(catheter["last_particle_m"], tip)), (catheter, tip)
assert len(last["instruments"]) == 2, last
# The last frame is the last cycle's state.
assert last["cycle"] == run["cycles"] - 1, (last["cycle"], run["cycles"])
PY
echo "telemetry stream test passed"
