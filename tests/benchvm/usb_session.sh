#!/usr/bin/env bash
# Runs inside the bench VM (tools/benchvm/benchvm run -- ...): loads the USB gadget stack
# (tools/benchvm/usb-gadget-modules), starts tools/usbgadget bound to dummy_hcd's UDC
# (dummy_udc.0), waits for the device to enumerate on the emulated host controller, kills it
# with SIGKILL and starts it again with --remove-stale (the stale gadget taken apart), runs
# usb_probe against it (descriptors, identity, 1,000 round trips, the watchdog), then stops the
# gadget with SIGTERM and checks that it unbound and removed its configfs gadget. Everything
# lands in $BENCHVM_OUT.
#   usb_session.sh BIN_DIR PROBE [probe options...]
# Exit status: 0 all checks passed; 1 a check failed; 10 the gadget did not enumerate.
set -uo pipefail
bin=$1 probe=$2
shift 2
out=${BENCHVM_OUT:?run me through benchvm run}
gadget=trainer_haptic_test
serial=benchvm-usb-0001

tools/benchvm/usb-gadget-modules || { echo "FAIL: USB gadget modules"; exit 10; }
# Waits (up to 30 s) until a USB device with our serial is on the bus; its sysfs directory in
# $device, empty when none came or the gadget exited.
wait_for_device() {
  device=
  for _ in $(seq 1 300); do
    for file in /sys/bus/usb/devices/*/serial; do
      [ -r "$file" ] && [ "$(cat "$file" 2>/dev/null)" = "$serial" ] && device=$(dirname "$file")
    done
    [ -n "$device" ] && return 0
    kill -0 "$pid" 2>/dev/null || return 1
    sleep 0.1
  done
  return 1
}
# The gadget is the device (separate hardware on a real bench): a real-time priority keeps the
# emulated host side from starving it.
start_gadget() {  # [extra usbgadget options]
  chrt -f 50 "$bin/usbgadget" --scene config/scenes/wall.toml --script builtin:hold --udc dummy_udc.0 \
    --gadget-name "$gadget" --serial "$serial" --events "$out/gadget_events.jsonl" "$@" \
    >"$out/gadget.txt" 2>&1 &
  pid=$!
}
status=0

# A gadget killed with SIGKILL stays in configfs (the kernel unbinds it when ep0 closes) with its
# functionfs mounted; the next start must refuse it, and take it apart with --remove-stale.
start_gadget
wait_for_device || { echo "FAIL: no USB device with serial $serial enumerated"; cat "$out/gadget.txt"; exit 10; }
kill -KILL "$pid"; wait "$pid" 2>/dev/null
[ -e "/sys/kernel/config/usb_gadget/$gadget" ] || { echo "FAIL: SIGKILL removed the gadget?"; status=1; }
if "$bin/usbgadget" --scene config/scenes/wall.toml --gadget-name "$gadget" >"$out/refused.txt" 2>&1; then
  echo "FAIL: a second usbgadget took over the stale gadget"; status=1
fi
grep -q "a gadget of this name exists" "$out/refused.txt" || { echo "FAIL: refusal message"; cat "$out/refused.txt"; status=1; }
start_gadget --remove-stale
if ! wait_for_device; then
  echo "FAIL: no USB device with serial $serial enumerated after --remove-stale"
  kill -TERM "$pid" 2>/dev/null; wait "$pid"
  cat "$out/gadget.txt"
  exit 10
fi
grep -q "removed the stale gadget" "$out/gadget.txt" || { echo "FAIL: --remove-stale did not say so"; status=1; }
echo "enumerated: $device $(cat "$device/idVendor"):$(cat "$device/idProduct") speed $(cat "$device/speed") Mb/s," \
  "product \"$(cat "$device/product")\", $(cat "$device/bNumInterfaces") interface(s)"
[ "$(cat "$device/speed")" = 480 ] || { echo "FAIL: not high speed"; status=1; }

"$probe" --serial "$serial" --json "$out/probe.json" "$@" || status=1

kill -TERM "$pid"
wait "$pid" || { echo "FAIL: usbgadget exited with $?"; status=1; }
cat "$out/gadget.txt"
[ ! -e "/sys/kernel/config/usb_gadget/$gadget" ] || { echo "FAIL: gadget $gadget left in configfs"; status=1; }
[ ! -e "$device/serial" ] || { echo "FAIL: the device is still on the bus after usbgadget stopped"; status=1; }
grep -q '"event":"watchdog_tripped"' "$out/gadget_events.jsonl" || { echo "FAIL: no watchdog_tripped event"; status=1; }
exit "$status"
