#!/usr/bin/env bash
# `trainer --check-rt` in the bench VM, whose guest runs Debian's PREEMPT_RT kernel: with a
# scene that makes preempt_rt fatal it must exit 0 there, preempt_rt must pass from
# /sys/kernel/realtime, and the IRQ check must see vcan0 as a virtual interface. Skips (77)
# where QEMU cannot run.
# usage: benchvm_check_rt_test.sh SOURCE_DIR TRAINER_BINARY
set -euo pipefail
src=$1
trainer=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sed -e "s|^device = \"../devices/sim.toml\"|device = \"$src/config/devices/canopen_vcan.toml\"|" \
    -e "s|^script = \"../trajectories/wall_press.csv\"|script = \"$src/config/trajectories/wall_press.csv\"|" \
    -e 's|^cpu_dma_latency_us = 0 .*|cpu_dma_latency_us = 0\nrt_check_fatal = ["preempt_rt", "memlock", "rtprio"]|' \
    "$src/config/scenes/wall.toml" >"$work/scene.toml"
status=0
"$src/tools/benchvm/benchvm" run --timeout 60 --out "$work" -- sh -c \
  "'$trainer' --check-rt --json --scene '$work/scene.toml' >'$work/check.json'; echo \$? >'$work/status'" ||
  status=$?
[ "$status" -ne 77 ] || exit 77
[ "$status" -eq 0 ] || { echo "FAIL: benchvm run exited with $status"; exit 1; }
python3 - "$work/check.json" "$(cat "$work/status")" <<'PY'
import json, sys
report = json.load(open(sys.argv[1]))
outcome = {c["check"]: c for c in report["checks"]}
assert sys.argv[2] == "0", f"--check-rt exited {sys.argv[2]} in the guest: {report}"
assert outcome["preempt_rt"]["outcome"] == "pass", outcome["preempt_rt"]
assert "/sys/kernel/realtime = 1" in outcome["preempt_rt"]["detail"], outcome["preempt_rt"]
assert outcome["irq_threads"]["outcome"] == "pass", outcome["irq_threads"]
assert "vcan0: virtual" in outcome["irq_threads"]["detail"], outcome["irq_threads"]
print("PASS:", {name: c["outcome"] for name, c in outcome.items()})
PY
