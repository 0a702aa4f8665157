#!/usr/bin/env bash
# `trainer --check-rt` in the bench VM, whose guest runs Debian's PREEMPT_RT kernel: with a
# scene that makes preempt_rt fatal it must exit 0 there, preempt_rt must pass from
# /sys/kernel/realtime, and the IRQ check must see vcan0 as a virtual interface; then the
# unit's RT limits for an unprivileged user (below). Skips (77) where QEMU cannot run.
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
# Then what trainer.service grants, without systemd: an unprivileged user (nobody) with no
# capabilities and no new privileges, RLIMIT_RTPRIO 95 and RLIMIT_MEMLOCK unlimited
# (LimitRTPRIO=, LimitMEMLOCK=): the self-check passes rtprio and memlock from the limits and a
# short run gets SCHED_FIFO 80 and locked memory.
chmod 0777 "$work"
cat >"$work/guest.sh" <<GUEST
#!/bin/sh
'$trainer' --check-rt --json --scene '$work/scene.toml' >'$work/check.json'; echo \$? >'$work/status'
prlimit --rtprio=95 --memlock=unlimited setpriv --reuid=nobody --regid=nogroup --clear-groups \
  --no-new-privs --inh-caps=-all --bounding-set=-all -- sh -c \
  "'$trainer' --check-rt --json --scene '$work/scene.toml' >'$work/user_check.json';
   '$trainer' --scene '$src/config/scenes/wall.toml' --hal sim --seconds 0.3 --slow-motion 20 \
     --overrun-streak-limit 1000 --report '$work/user_run.json' >'$work/user_run.txt' 2>&1"
GUEST
chmod +x "$work/guest.sh"
status=0
# From the source tree: the guest sees the caller's working directory even under /tmp (its own
# tmpfs hides the rest of the host's /tmp), and with it the build tree inside the source tree.
cd "$src"
tools/benchvm/benchvm run --timeout 60 --out "$work" -- "$work/guest.sh" || status=$?
[ "$status" -ne 77 ] || exit 77
[ "$status" -eq 0 ] || { echo "FAIL: benchvm run exited with $status"; exit 1; }
python3 - "$work/check.json" "$(cat "$work/status")" "$work/user_check.json" "$work/user_run.json" <<'PY'
import json, sys
report = json.load(open(sys.argv[1]))
outcome = {c["check"]: c for c in report["checks"]}
assert sys.argv[2] == "0", f"--check-rt exited {sys.argv[2]} in the guest: {report}"
assert outcome["preempt_rt"]["outcome"] == "pass", outcome["preempt_rt"]
assert "/sys/kernel/realtime = 1" in outcome["preempt_rt"]["detail"], outcome["preempt_rt"]
assert outcome["irq_threads"]["outcome"] == "pass", outcome["irq_threads"]
assert "vcan0: virtual" in outcome["irq_threads"]["detail"], outcome["irq_threads"]
user = {c["check"]: c for c in json.load(open(sys.argv[3]))["checks"]}
assert user["rtprio"]["outcome"] == "pass" and "RLIMIT_RTPRIO 95" in user["rtprio"]["detail"], user["rtprio"]
assert user["memlock"]["outcome"] == "pass" and "RLIMIT_MEMLOCK is unlimited" in user["memlock"]["detail"], user["memlock"]
rt = json.load(open(sys.argv[4]))["rt"]
assert rt["policy"] == "SCHED_FIFO" and rt["priority"] == 80 and rt["memory_locked"] is True, rt
print("PASS:", {name: c["outcome"] for name, c in outcome.items()})
print(f"PASS: as nobody with no capabilities and the unit's limits: {rt['policy']} {rt['priority']}, "
      f"memory locked, on {rt['kernel_release']}")
PY
