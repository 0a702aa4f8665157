#!/bin/sh
# The scripted bench engineer of hil's GPIO check in the bench VM (hil --act "hil_io_act.sh
# MODE"): each operator action of the GPIO part done on the gpio-sim chip's simulated pulls
# (HIL_SIM_BASE = /sys/devices/platform/<dev>/<chip>, lines estop enable drive_enable fault_lamp
# spare at offsets 0..4).
#   hil_io_act.sh good ACTION   the lines as wired: the e-stop press is a pull-up/pull-down of
#                               line 0, the enable switch line 1
#   hil_io_act.sh dead ACTION   a dead e-stop line: the "press" reaches line 4 (spare, a hog
#                               output: its pull changes nothing), never 0
# Unknown actions fail (hil takes that as declined). POSIX sh (dash): it runs once per
# action, and dash starts several times faster than bash under TCG.
set -eu
mode=$1 action=$2
base=${HIL_SIM_BASE:?}
pull() { echo "$2" >"$base/sim_gpio$1/pull"; }
estop=0
[ "$mode" = good ] || estop=4
case "$action" in
  gpio.estop.press) pull "$estop" pull-up; pull "$estop" pull-down ;;
  gpio.enable.hold) pull 1 pull-up ;;
  gpio.enable.release) pull 1 pull-down; pull 1 pull-up ;;
  *) echo "hil_io_act: unknown action $action" >&2; exit 1 ;;
esac
