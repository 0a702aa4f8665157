#!/usr/bin/env bash
# Unplug through the whole trainer: in the bench VM the trainer runs the wall scene over USB
# against usbgadget; mid-run the gadget is unbound from its device controller (its configfs
# UDC file set to ""), which is what the host sees when the cable is pulled. The trainer must
# latch device_lost within one cycle of libusb reporting the loss (report: usb.device_lost,
# the RT cycle count when the library reported it and when the cycle latched it), latch the
# safety fault device_lost, zero the outputs and exit 3 (completed with a fault).
#   usb_unplug_test.sh SOURCE_DIR BIN_DIR [SLOW_MOTION] [OUT_DIR]
# Exit 77 (skip) when the bench VM cannot run here.
set -euo pipefail
src=$1 bin=$2 slow=${3:-16}
work=${4:-$(mktemp -d)}
[ $# -ge 4 ] || trap 'rm -rf "$work"' EXIT
mkdir -p "$work"
cd "$src"
scene=config/scenes/wall.toml
device=config/devices/usb_benchvm.toml
# 1500 cycles of 1 ms at slow motion x16 = 24 s of wall time; the unplug comes after 10 s.
status=0
tools/benchvm/benchvm run --smp 2 --timeout 300 --out "$work" -- \
  tests/benchvm/usb_trainer_session.sh "$bin" "$scene" "$device" 1000 1500 "$slow" 10 || status=$?
[ "$status" -ne 77 ] || exit 77
if [ "$status" -ne 3 ]; then
  echo "FAIL: the trainer exited with $status, expected 3 (completed with a fault latched)"
  exit 1
fi
python3 - "$work/usb_report.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
usb = r["usb"]
lost = usb["device_lost"]
failures = []
def check(name, value, ok):
    print(f"{name:<40} {value!s:>24}  {'ok' if ok else 'FAIL'}")
    if not ok:
        failures.append(name)
check("device_lost reported", lost is not None, lost is not None)
if lost is not None:
    delay = lost["latched_at_cycle"] - lost["reported_at_cycle"]
    check("source", lost["source"], lost["source"] in ("hotplug", "transfer"))
    check("reported at cycle", lost["reported_at_cycle"], lost["reported_at_cycle"] > 100)
    check("latched cycles after the report", delay, 0 <= delay <= 1)
    check("latch delay us (shown)", lost["latch_delay_us"], True)
    check("safety first fault cycle", r["safety"]["first_fault_cycle"],
          abs(r["safety"]["first_fault_cycle"] - (lost["latched_at_cycle"] - 1)) <= 1)
check("safety first fault", r["safety"]["first_fault"], r["safety"]["first_fault"] == "device_lost")
check("usb faults", usb["faults"], usb["faults"].startswith("device_lost"))
check("outputs zeroed at exit", r["safety"]["outputs_zeroed_at_exit"],
      r["safety"]["outputs_zeroed_at_exit"])
check("heap after arming", r["memory"]["heap_allocations_after_arming"],
      r["memory"]["heap_allocations_after_arming"] == 0)
if failures:
    print("FAILED: " + ", ".join(failures))
    sys.exit(1)
print("unplug latched within one cycle of libusb's report")
PY
