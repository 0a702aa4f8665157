#!/usr/bin/env bash
# The cbd scene over a real kernel USB stack: in the bench VM the trainer (libusb backend) and
# usbgadget (the USB haptic interface on FunctionFS with the simulated plant) run as two
# processes through the scripted insertion; the trainer's report is then compared with the
# same scene on the simulated bench in simulated time (compare_reports.py: stated tolerances).
#   usb_cbd_test.sh SOURCE_DIR BIN_DIR [SLOW_MOTION] [OUT_DIR|-] [CYCLES]
# OUT_DIR: where the logs and reports stay; absent or - : a temporary directory, removed.
# CYCLES: the first CYCLES cycles of the script only (both runs alike), as can_cbd_test.sh;
# default the whole script. CI runs 7000 (contacts, grasp, insertion target reached).
# Exit 77 (skip) when the bench VM cannot run here.
set -euo pipefail
src=$1 bin=$2 slow=${3:-8}
work=${4:--}
length=()
[ -z "${5:-}" ] || length=(--cycles "$5")
if [ "$work" = - ]; then work=$(mktemp -d); trap 'rm -rf "$work"' EXIT; fi
mkdir -p "$work"
cd "$src"
scene=config/scenes/cbd.toml
device=config/devices/usb_benchvm.toml
"$bin/modelc" build --scene "$scene" >/dev/null
"$bin/trainer" --scene "$scene" --device "$device" --hal sim --time simulated "${length[@]}" \
  --report "$work/sim_report.json" >"$work/sim.txt"
cycles=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['cycles'])" "$work/sim_report.json")
# Two virtual CPUs, slow motion 8: as the CAN cbd session (can_cbd_test.sh).
status=0
tools/benchvm/benchvm run --smp 2 --timeout 900 --out "$work" -- \
  tests/benchvm/usb_trainer_session.sh "$bin" "$scene" "$device" 1000 "$cycles" "$slow" || status=$?
[ "$status" -ne 77 ] || exit 77
if [ "$status" -ne 0 ]; then
  echo "FAIL: the USB session exited with $status"
  tail -n 30 "$work/usbgadget.txt" 2>/dev/null || true
  exit 1
fi
python3 tests/benchvm/compare_reports.py "$work/sim_report.json" "$work/usb_report.json"
