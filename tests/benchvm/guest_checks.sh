#!/usr/bin/env bash
# Runs inside the bench VM (benchvm_smoke_test.sh starts it with `benchvm run`): proves the
# guest is the PREEMPT_RT kernel and that SocketCAN works end to end on vcan0 with the host's
# can-utils and python3. Each check prints one line; the first failure exits non-zero.
# usage: guest_checks.sh   (in the guest; writes $BENCHVM_OUT/guest-checks.txt on success)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)

fail() { echo "FAIL: $*"; exit 1; }
ok() { echo "ok: $*"; }

[ "${BENCHVM:-}" = 1 ] || fail "not inside the bench VM (BENCHVM unset)"

# The kernel: Debian's PREEMPT_RT build.
[[ $(uname -v) == *PREEMPT_RT* ]] || fail "uname -v '$(uname -v)' does not say PREEMPT_RT"
[ "$(cat /sys/kernel/realtime 2>/dev/null)" = 1 ] || fail "/sys/kernel/realtime is not 1"
ok "kernel $(uname -r) is PREEMPT_RT"

# The host root is read-only, /tmp is the guest's own.
if touch /usr/.benchvm-write-test 2>/dev/null; then fail "the host root is writable"; fi
tmp=$(mktemp -d)
ok "host root read-only, /tmp writable ($tmp)"

# vcan0 is up.
ip -details link show vcan0 | grep -q 'vcan' || fail "vcan0 missing: $(ip -br link)"
ip link show vcan0 | grep -q ',UP' || fail "vcan0 is not up"
ok "vcan0 up"

# can-utils: candump receives what cansend sends. candump has no readiness signal, so the
# frame is sent until candump has received one (-n 1) or 5 s have passed.
candump -L -n 1 -T 5000 vcan0 >"$tmp/dump.log" &
dump_pid=$!
for _ in $(seq 50); do
  kill -0 "$dump_pid" 2>/dev/null || break
  cansend vcan0 123#DEADBEEF
  sleep 0.1
done
wait "$dump_pid" || fail "candump exited with $?"
grep -q ' vcan0 123#DEADBEEF$' "$tmp/dump.log" || fail "candump got '$(cat "$tmp/dump.log")'"
ok "candump -L vcan0 received cansend's frame: $(cut -d' ' -f2- "$tmp/dump.log")"

# Raw sockets from python3: error frames enabled, a frame between two sockets, and the CAN
# gateway (can-gw) routing vcan0 to a second vcan.
ip link add dev vcan1 type vcan
ip link set vcan1 up
cangw -A -s vcan0 -d vcan1 -e
python3 "$here/raw_can_check.py" vcan0 vcan1 || fail "raw_can_check.py exited with $?"

echo "all checks passed in $(uname -r)" >"$BENCHVM_OUT/guest-checks.txt"
ok "result written to $BENCHVM_OUT/guest-checks.txt"
