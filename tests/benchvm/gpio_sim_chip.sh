#!/usr/bin/env bash
# A simulated GPIO chip in the bench VM (gpio-sim, loaded by `benchvm run --gpio-sim`), driven
# through configfs and sysfs the way a bench's wiring would be: inputs by their pull, outputs
# read back from their value. Guest side only (needs /sys/kernel/config/gpio-sim).
#
#   gpio_sim_chip.sh create DEVICE LABEL NAME...   one bank, one line per NAME (offset 0, 1, ...),
#                                                  "-" leaves a line unnamed, NAME@DIRECTION
#                                                  makes the line a hog held by the kernel
#                                                  (input, output-high, output-low); prints the
#                                                  chip name the kernel gave it (gpiochipN)
#   gpio_sim_chip.sh chip DEVICE                   the chip name (read from configfs)
#   gpio_sim_chip.sh press DEVICE OFFSET           pull-up: the input reads 1 (physical level)
#   gpio_sim_chip.sh release DEVICE OFFSET         pull-down: the input reads 0
#   gpio_sim_chip.sh pull DEVICE OFFSET            the line's pull (pull-up / pull-down)
#   gpio_sim_chip.sh value DEVICE OFFSET           the line's value (0/1): what an output drives,
#                                                  or an input's pull
#   gpio_sim_chip.sh remove DEVICE                 take the chip down and remove it
#
# Names are never assumed: the chip name comes from the bank's chip_name and the platform
# device from the device's dev_name, both read from configfs after `live`.
set -euo pipefail

configfs=/sys/kernel/config/gpio-sim

die() { echo "gpio_sim_chip: $*" >&2; exit 1; }

[ -d "$configfs" ] || die "$configfs missing (run the VM with benchvm run --gpio-sim)"

sim_dir() {  # DEVICE
  local dir=$configfs/$1
  [ -d "$dir" ] || die "no gpio-sim device '$1' in $configfs"
  echo "$dir"
}

line_dir() {  # DEVICE OFFSET: the sysfs directory of one simulated line
  local dir dev chip
  dir=$(sim_dir "$1")
  [[ $2 =~ ^[0-9]+$ ]] || die "offset '$2' is not a number"
  dev=$(cat "$dir/dev_name")
  chip=$(cat "$dir/bank0/chip_name")
  [ -d "/sys/devices/platform/$dev/$chip/sim_gpio$2" ] \
    || die "no line $2 on $chip (/sys/devices/platform/$dev/$chip/sim_gpio$2)"
  echo "/sys/devices/platform/$dev/$chip/sim_gpio$2"
}

cmd=${1:-}
[ $# -ge 2 ] || die "usage: gpio_sim_chip.sh create|chip|press|release|pull|value|remove DEVICE ..."
shift
case "$cmd" in
  create)
    [ $# -ge 3 ] || die "usage: gpio_sim_chip.sh create DEVICE LABEL NAME..."
    device=$1 label=$2
    shift 2
    dir=$configfs/$device
    [ ! -e "$dir" ] || die "gpio-sim device '$device' exists already"
    mkdir "$dir" "$dir/bank0"
    echo "$label" >"$dir/bank0/label"
    echo $# >"$dir/bank0/num_lines"
    offset=0
    for name in "$@"; do
      if [ "$name" != - ]; then
        mkdir "$dir/bank0/line$offset"
        echo "${name%@*}" >"$dir/bank0/line$offset/name"
        if [[ $name == *@* ]]; then
          mkdir "$dir/bank0/line$offset/hog"
          echo "${name%@*}-hog" >"$dir/bank0/line$offset/hog/name"
          echo "${name#*@}" >"$dir/bank0/line$offset/hog/direction"
        fi
      fi
      offset=$((offset + 1))
    done
    echo 1 >"$dir/live"
    chip=$(cat "$dir/bank0/chip_name")
    [ -e "/dev/$chip" ] || die "chip $chip of '$device' has no /dev/$chip"
    echo "$chip"
    ;;
  chip) cat "$(sim_dir "$1")/bank0/chip_name" ;;
  press) echo pull-up >"$(line_dir "$1" "$2")/pull" ;;
  release) echo pull-down >"$(line_dir "$1" "$2")/pull" ;;
  pull) cat "$(line_dir "$1" "$2")/pull" ;;
  value) cat "$(line_dir "$1" "$2")/value" ;;
  remove)
    dir=$(sim_dir "$1")
    echo 0 >"$dir/live"
    for line in "$dir"/bank0/line*; do
      [ ! -d "$line/hog" ] || rmdir "$line/hog"
      [ ! -d "$line" ] || rmdir "$line"
    done
    rmdir "$dir/bank0" "$dir"
    ;;
  *) die "unknown command '$cmd'" ;;
esac
