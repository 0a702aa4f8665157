#!/usr/bin/env bash
# The trainer with its e-stop, enable switch, drive-enable and fault-lamp lines on a real kernel
# GPIO chip (gpio-sim) in the bench VM (gpio_trainer.py), in two sessions of one VM boot:
#  - sim: the simulated bench's motion + the lines (config/devices/gpio_sim_bench.toml);
#  - can: ten CiA 402 drives (simdrive) on vcan0 + the lines (canopen_vcan_gpio.toml);
#  - enable: the simulated motion again, the scene requiring the enable switch.
# In sim and can, a short e-stop press latches `estop`; in enable, a short release of the enable
# switch latches `enable_released`. Each time zero force from that cycle, the drive-enable line
# falls and stays low after the line recovered, the fault lamp lights.
#   gpio_trainer_test.sh SOURCE_DIR BIN_DIR [OUT_DIR]
set -euo pipefail
src=$1 bin=$2
work=${3:-$(mktemp -d)}
[ $# -ge 3 ] || trap 'rm -rf "$work"' EXIT
mkdir -p "$work"
cd "$src"
status=0
tools/benchvm/benchvm run --gpio-sim --smp 2 --timeout 300 --out "$work" -- bash -c "
  python3 tests/benchvm/gpio_trainer.py sim '$bin' 8 700 >'$work/sim.guest.txt' 2>&1; s=\$?
  python3 tests/benchvm/gpio_trainer.py can '$bin' 16 450 config/devices/canopen_vcan_gpio.toml \
    simdrive >'$work/can.guest.txt' 2>&1; c=\$?
  python3 tests/benchvm/gpio_trainer.py enable '$bin' 8 700 config/devices/gpio_sim_bench.toml - \
    enable >'$work/enable.guest.txt' 2>&1; e=\$?
  cat '$work/sim.guest.txt' '$work/can.guest.txt' '$work/enable.guest.txt'
  [ \$s -eq 0 ] && [ \$c -eq 0 ] && [ \$e -eq 0 ]" || status=$?
[ "$status" -ne 77 ] || exit 77
fail() { echo "FAIL: $*"; exit 1; }
for name in sim can enable; do
  sed "s/^/  $name trainer | /" "$work/$name.trainer.txt" 2>/dev/null || true
  log=$work/$name.guest.txt
  [ -f "$log" ] || fail "$name: no guest output"
  expect() { grep -qE -- "$1" "$log" || fail "$name: expected in the guest's output: $1"; }
  expect "^before_start drive_enable=0 fault_lamp=0"
  expect "^armed=yes"
  expect "^armed_lamp fault_lamp=0"
  expect "^drive_enable_fell=yes"
  expect "^after_release samples=[1-9][0-9]* drive_enable_high=0 fault_lamp_off=0"
  expect "^trainer_exit=3"  # 3: the run ended with a fault (the e-stop), as it must
  expect "^after_exit drive_enable=0"
  hal=sim+gpio fault=estop
  [ "$name" != can ] || { hal=canopen+gpio; expect "^simdrive_exit=0"; }
  [ "$name" != enable ] || fault=enable_released
  python3 - "$work/$name.trainer.json" "$hal" "$fault" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
s = r["safety"]
print(f"report: hal {r['hal']}, first fault {s['first_fault']} at cycle {s['first_fault_cycle']}, "
      f"armed cycles {r['armed_cycles']} of {r['cycles']}, outputs zeroed {s['outputs_zeroed_at_exit']}, "
      f"heap after arming {r['memory']['heap_allocations_after_arming']}")
ok = (r["hal"] == sys.argv[2] and s["first_fault"] == sys.argv[3] and s["arm_count"] == 1
      and r["armed_cycles"] <= s["first_fault_cycle"] and s["outputs_zeroed_at_exit"]
      and r["memory"]["heap_allocations_after_arming"] == 0)
if sys.argv[2].startswith("canopen"):
    # The bus's figures come from the motion half of the composite device.
    bus = r.get("can") or {}
    print(f"report: can block: {bus.get('sync_sent', 'missing')} SYNCs sent")
    ok = ok and bus.get("sync_sent", 0) > 0
sys.exit(0 if ok else 1)
PY
done
[ "$status" -eq 0 ] || fail "the guest exited with $status"
echo "PASS"
