#!/usr/bin/env bash
# The trainer with its e-stop, enable switch, drive-enable and fault-lamp lines on a real kernel
# GPIO chip (gpio-sim) in the bench VM (gpio_trainer.py): a half-period e-stop press latches
# `estop`, zero force from that cycle, the drive-enable line falls and stays low.
#   gpio_trainer_test.sh SOURCE_DIR BIN_DIR [OUT_DIR]
set -euo pipefail
src=$1 bin=$2
work=${3:-$(mktemp -d)}
[ $# -ge 3 ] || trap 'rm -rf "$work"' EXIT
mkdir -p "$work"
cd "$src"
slow=8 cycles=1500
status=0
tools/benchvm/benchvm run --gpio-sim --smp 2 --timeout 240 --out "$work" -- \
  python3 tests/benchvm/gpio_trainer.py "$bin" "$slow" "$cycles" | tee "$work/guest.txt" || status=$?
[ "$status" -ne 77 ] || exit 77
sed 's/^/  trainer | /' "$work/trainer.txt" 2>/dev/null || true
fail() { echo "FAIL: $*"; exit 1; }
[ "$status" -eq 0 ] || fail "the guest exited with $status"
log=$work/guest.txt
expect() { grep -qE -- "$1" "$log" || fail "expected in the guest's output: $1"; }
expect "^before_start drive_enable=0 fault_lamp=0"
expect "^armed=yes"
expect "^armed_lamp fault_lamp=0"
expect "^drive_enable_fell=yes"
expect "^after_release samples=[1-9][0-9]* drive_enable_high=0 fault_lamp_off=0"
expect "^trainer_exit=3"  # 3: the run ended with a fault (the e-stop), as it must
expect "^after_exit drive_enable=0"
python3 - "$work/trainer.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
s = r["safety"]
print(f"report: hal {r['hal']}, first fault {s['first_fault']} at cycle {s['first_fault_cycle']}, "
      f"armed cycles {r['armed_cycles']} of {r['cycles']}, outputs zeroed {s['outputs_zeroed_at_exit']}, "
      f"heap after arming {r['memory']['heap_allocations_after_arming']}")
ok = (r["hal"] == "sim+gpio" and s["first_fault"] == "estop" and s["arm_count"] == 1
      and r["armed_cycles"] <= s["first_fault_cycle"] and s["outputs_zeroed_at_exit"]
      and r["memory"]["heap_allocations_after_arming"] == 0)
sys.exit(0 if ok else 1)
PY
echo "PASS"
