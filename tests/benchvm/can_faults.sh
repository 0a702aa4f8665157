#!/usr/bin/env bash
# Runs inside the bench VM: every fault simdrive can inject, each in its own short session of the
# wall scene over vcan0 (trainer + simdrive, slow motion: 16 in the test, so that an emulator
# hiccup is not two SYNC periods long), scheduled at the drives' SYNC 200.
# The trainer's report must show the fault latched within a few cycles of the drives acting
# and the instrument disarmed (zero force) from then on; check_faults.py judges.
#   can_faults.sh BIN_DIR SLOW_MOTION
set -uo pipefail
bin=$1 slow=$2
out=${BENCHVM_OUT:?run me through benchvm run}
scene=config/scenes/wall.toml
device=config/devices/canopen_vcan.toml
specs=(
  "emcy:node=3,at_sync=200"
  "bus_off:at_sync=200"
  "reboot:node=4,at_sync=200"
  "corrupt:node=2,at_sync=200"
  "corrupt:node=2,mode=bits,at_sync=200"
  "silent:node=5,at_sync=200"
  "drop:node=1,at_sync=200"
  "delay:node=1,ms=20,at_sync=200"
  "lost_sync:node=1,count=2,at_sync=200"
  "encoder_jump:node=1,counts=4096,at_sync=200"
)
i=0
for spec in "${specs[@]}"; do
  chrt -f 50 "$bin/simdrive" --scene "$scene" --device "$device" --slow-motion "$slow" --no-stdin \
    --fault "$spec" --events "$out/fault_$i.events.jsonl" >"$out/fault_$i.simdrive.txt" 2>&1 &
  sim=$!
  # The drives up before the master, as on a bench (simdrive_booted.sh says why).
  if ! tests/benchvm/simdrive_booted.sh "$out/fault_$i.events.jsonl" "$out/fault_$i.simdrive.txt" \
      "$sim"; then
    echo "$spec -> simdrive did not come up"
    kill -INT "$sim" 2>/dev/null
    exit 10
  fi
  "$bin/trainer" --scene "$scene" --device "$device" --cycles 260 --slow-motion "$slow" --no-rt \
    --report "$out/fault_$i.json" >"$out/fault_$i.trainer.txt" 2>&1
  echo "$spec -> trainer exit $?"
  kill -INT "$sim" 2>/dev/null
  wait "$sim"
  echo "$spec" >"$out/fault_$i.spec"
  i=$((i + 1))
done
exit 0
