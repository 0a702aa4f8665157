#!/usr/bin/env bash
# Runs inside the bench VM (benchvm run --gpio-sim): hil_io's GPIO part against a gpio-sim chip
# wired as config/devices/gpio_sim_bench.toml says (tests/benchvm/hil_io_test.sh judges).
#   hil_io.sh BIN_DIR TRIALS SLOW_MOTION [gpio-only]
#  1. good bench: `hil_io scan` and `hil_io check --yes --act "hil_io_act.sh good"` (TRIALS
#     presses of the e-stop, releases of the enable switch, the outputs read back);
#  2. a device file naming a line the chip lacks: scan fails naming it;
#  3. dead e-stop line (the act script's press reaches another line): check fails the e-stop
#     step with "no edge on <chip>:0 (estop) within 3 s — check wiring".
# Writes $BENCHVM_OUT/<case>.{json,txt,status}.
set -uo pipefail
bin=$1 trials=$2 slow=$3 only=${4:-}
out=${BENCHVM_OUT:?run me through benchvm run}
device=config/devices/gpio_sim_bench.toml
chip=$(tests/benchvm/gpio_sim_chip.sh create trainer trainer-bench estop enable drive_enable \
  fault_lamp spare) || { echo "FAIL: cannot create the gpio-sim chip"; exit 1; }
export HIL_SIM_BASE=/sys/devices/platform/$(cat /sys/kernel/config/gpio-sim/trainer/dev_name)/$chip
echo "gpio-sim chip: $chip ($HIL_SIM_BASE)"
run() {  # NAME ARGS...: hil_io ARGS --json to NAME.json, stderr to NAME.txt, status to NAME.status
  local name=$1 t0=$EPOCHREALTIME
  shift
  "$bin/hil_io" "$@" --json >"$out/$name.json" 2>"$out/$name.txt"
  echo $? >"$out/$name.status"
  echo "$name: exit $(cat "$out/$name.status") after $(( (${EPOCHREALTIME/./} - ${t0/./}) / 1000 )) ms"
}
run gpio_scan scan --part gpio --device "$device"
run gpio_check check --part gpio --device "$device" --yes --act "tests/benchvm/hil_io_act.sh good" \
  --slow-motion "$slow" --trials "$trials"
[ "$only" = gpio-only ] && exit 0
sed 's/^line = "fault_lamp"/line = "fault_lmp"/' "$device" >"$out/miswired.toml"
run gpio_scan_miswired scan --part gpio --device "$out/miswired.toml"
run gpio_check_dead check --part gpio --device "$device" --yes \
  --act "tests/benchvm/hil_io_act.sh dead" --slow-motion "$slow" --trials 2 --action-timeout 3
exit 0
