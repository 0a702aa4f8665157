#!/usr/bin/env bash
# Runs inside the bench VM (tools/benchvm/benchvm run -- ...), on the RT kernel's vcan0: the
# trainer as one process, simdrive (the simulated CiA 402 drives) as another, candump logging
# the bus, then candecode over the log. Everything lands in $BENCHVM_OUT.
#   can_session.sh BIN_DIR SCENE DEVICE PERIOD_US CYCLES SLOW_MOTION [simdrive --fault SPEC ...]
# SLOW_MOTION: both processes run real time slowed by this factor (--slow-motion), because
# the emulator runs the cycle ~20x slower than the hardware; the bus, not the wall clock, sets
# the plant's time, so the physics is the same at any factor. The overrun-streak fault is raised
# to 1000 cycles: the emulator stalls now and then for longer than 10 periods (seen once at
# x16), which says nothing about the code; the CAN side's own deadlines stay as they are.
# Exit status: the trainer's (0 completed, 3 completed with a fault latched), or 10 when
# simdrive or candecode failed.
set -uo pipefail
bin=$1 scene=$2 device=$3 period_us=$4 cycles=$5 slow=$6
shift 6
out=${BENCHVM_OUT:?run me through benchvm run}

# candump writes to the guest's tmpfs (a 9p write per frame would slow the bus down) and the
# log is copied out at the end.
candump -L vcan0 >/tmp/session.log 2>"$out/candump.err" &
dump=$!
# The drives are separate hardware on a real bench: here they get a real-time priority so that
# the emulated trainer (or candump) never starves them.
chrt -f 50 "$bin/simdrive" --scene "$scene" --device "$device" --period-us "$period_us" --slow-motion "$slow" \
  --no-stdin --events "$out/simdrive_events.jsonl" "$@" >"$out/simdrive.txt" 2>&1 &
sim=$!
# The drives up before the master, as on a bench (simdrive_booted.sh says why).
tests/benchvm/simdrive_booted.sh "$out/simdrive_events.jsonl" "$out/simdrive.txt" "$sim" || {
  kill -INT "$sim" 2>/dev/null; kill -INT "$dump" 2>/dev/null; exit 10; }
"$bin/trainer" --scene "$scene" --device "$device" --period-us "$period_us" --cycles "$cycles" \
  --slow-motion "$slow" --overrun-streak-limit 1000 --no-rt --report "$out/can_report.json" \
  >"$out/trainer.txt" 2>&1
status=$?
sleep 0.2  # the drives' reaction to the master going away is part of the log
kill -INT "$sim" 2>/dev/null
wait "$sim"
sim_status=$?
kill -INT "$dump" 2>/dev/null
wait "$dump" 2>/dev/null
cp /tmp/session.log "$out/session.log"
"$bin/candecode" --device "$device" "$out/session.log" >"$out/decoded.txt"
decode_status=$?
tail -n 1 "$out/decoded.txt"
cat "$out/trainer.txt"
echo "trainer exit $status, simdrive exit $sim_status, candecode exit $decode_status"
if [ "$sim_status" -ne 0 ] || [ "$decode_status" -ne 0 ]; then exit 10; fi
exit "$status"
