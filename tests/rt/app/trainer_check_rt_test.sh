#!/usr/bin/env bash
# `trainer --check-rt` and the self-check before arming, end to end with the real binary: over
# an empty root (nothing passes) a scene listing preempt_rt as fatal exits 1 and a real-time
# run refuses to arm with the check's message; simulated time skips the check; on the live
# system --json answers every check and the exit status follows the kernel's PREEMPT_RT state.
# usage: trainer_check_rt_test.sh TRAINER_BINARY REPO_DIR
set -euo pipefail
trainer=$1
repo=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir "$work/empty_root"
sed -e "s|^device = \"../devices/sim.toml\"|device = \"$repo/config/devices/sim.toml\"|" \
    -e "s|^script = \"../trajectories/wall_press.csv\"|script = \"$repo/config/trajectories/wall_press.csv\"|" \
    -e 's|^cpu_dma_latency_us = 0 .*|cpu_dma_latency_us = 0\nrt_check_fatal = ["preempt_rt", "memlock"]|' \
    "$repo/config/scenes/wall.toml" >"$work/scene.toml"
grep -q '^rt_check_fatal' "$work/scene.toml"

status=0
"$trainer" --check-rt --scene "$work/scene.toml" --rt-check-root "$work/empty_root" \
  >"$work/check.txt" || status=$?
cat "$work/check.txt"
[ "$status" -eq 1 ] || { echo "--check-rt over an empty root: exit $status, expected 1"; exit 1; }
grep -q '^  FATAL preempt_rt' "$work/check.txt"
grep -q 'fix: apt install linux-image-rt-amd64' "$work/check.txt"

status=0
"$trainer" --scene "$work/scene.toml" --hal sim --seconds 0.2 --rt-check-root "$work/empty_root" \
  >"$work/run.txt" 2>&1 || status=$?
[ "$status" -eq 1 ] || { echo "run with a fatal failure: exit $status, expected 1"; cat "$work/run.txt"; exit 1; }
grep -q 'RT self-check failed; not arming' "$work/run.txt" || { cat "$work/run.txt"; exit 1; }
grep -q 'preempt_rt: ' "$work/run.txt"
echo "refused to arm: $(head -n1 "$work/run.txt")"

"$trainer" --scene "$work/scene.toml" --hal sim --time simulated --cycles 100 \
  --rt-check-root "$work/empty_root" --report-dir "$work/reports" >"$work/sim.txt" 2>&1 ||
  { cat "$work/sim.txt"; exit 1; }
# --report-dir (the appliance's reports): timestamped files, latest.json -> the newest.
"$trainer" --scene "$work/scene.toml" --hal sim --time simulated --cycles 100 \
  --report-dir "$work/reports" >"$work/sim2.txt" 2>&1 || { cat "$work/sim2.txt"; exit 1; }
[ "$(ls "$work/reports" | grep -c '^wall-[0-9]\{8\}T[0-9]\{6\}Z.*\.json$')" -eq 2 ] ||
  { ls -l "$work/reports"; exit 1; }
newest=$(grep -o 'report: .*' "$work/sim2.txt" | cut -d' ' -f2)
[ "$(readlink -f "$work/reports/latest.json")" = "$(readlink -f "$newest")" ] ||
  { echo "latest.json does not point at $newest"; ls -l "$work/reports"; exit 1; }

status=0
"$trainer" --check-rt --json --scene "$work/scene.toml" >"$work/live.json" || status=$?
python3 - "$work/live.json" "$status" <<'PY'
import json, os, platform, sys
report = json.load(open(sys.argv[1]))
status = int(sys.argv[2])
names = [c["check"] for c in report["checks"]]
assert names == ["preempt_rt", "isolated_cpu", "cpu_dma_latency", "cpu_governor", "smt",
                 "rt_throttling", "memlock", "rtprio", "irq_threads"], names
rt = platform.uname().version.find("PREEMPT_RT") >= 0 or (
    os.path.exists("/sys/kernel/realtime") and open("/sys/kernel/realtime").read().strip() == "1")
preempt = report["checks"][0]
assert (preempt["outcome"] == "pass") == rt, preempt
fatal = [c["check"] for c in report["checks"] if c["fatal"]]
assert report["passed"] == (not fatal) and status == (1 if fatal else 0), (status, fatal)
for check in report["checks"]:
    assert check["outcome"] == "pass" or check["fix"], check
print("live system:", {c["check"]: c["outcome"] for c in report["checks"]}, "exit", status)
PY
