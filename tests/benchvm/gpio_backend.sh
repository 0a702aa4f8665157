#!/usr/bin/env bash
# Runs inside the bench VM (benchvm run --gpio-sim): the GPIO backend against a gpio-sim chip.
#   gpio_backend.sh BIN_DIR smoke
#       the chip appears with its line names in libgpiod's listing, a pull change is read
#       through libgpiod;
#   gpio_backend.sh BIN_DIR lines PRESSES PERIOD_US
#       the smoke checks, then GpioDevice::configure() case by case (gpiod_bench configure), then
#       PRESSES e-stop
#       presses of less than a period at random phases through the simulated pull, every one
#       latched (gpiod_bench presses).
# Output for the host side to judge; exit status 0 when everything held.
set -uo pipefail
bin=$1 what=$2
chip_sh=tests/benchvm/gpio_sim_chip.sh
label=trainer-bench
chip=$("$chip_sh" create trainer "$label" estop enable drive_enable fault_lamp - hogged@output-high) \
  || { echo "FAIL: cannot create the gpio-sim chip"; exit 1; }
echo "gpio-sim chip: $chip (label $label, platform device $(cat /sys/kernel/config/gpio-sim/trainer/dev_name))"
status=0
smoke() {
  "$bin/gpiod_bench" list "$label" || status=1
  before=$("$bin/gpiod_bench" get "$label" 0)
  "$chip_sh" press trainer 0
  pressed=$("$bin/gpiod_bench" get "$label" 0)
  "$chip_sh" release trainer 0
  released=$("$bin/gpiod_bench" get "$label" 0)
  echo "estop through libgpiod: $before, after pull-up $pressed, after pull-down $released"
  [ "$before/$pressed/$released" = 0/1/0 ] || status=1
}
case "$what" in
  smoke) smoke ;;
  lines)
    smoke
    "$bin/gpiod_bench" configure "$label" || status=1
    echo "drive_enable after the configure cases (released, back to its pull): $("$chip_sh" value trainer 2)"
    dev=$(cat /sys/kernel/config/gpio-sim/trainer/dev_name)
    "$bin/gpiod_bench" presses "$label" "/sys/devices/platform/$dev/$chip/sim_gpio0/pull" "$3" "$4" \
      || status=1
    ;;
  *) echo "unknown: $what"; status=2 ;;
esac
"$chip_sh" remove trainer || status=1
exit "$status"
