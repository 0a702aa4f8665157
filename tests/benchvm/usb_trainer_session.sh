#!/usr/bin/env bash
# Runs inside the bench VM (tools/benchvm/benchvm run -- ...), on the RT kernel's USB stack
# (dummy_hcd: a host controller and a device controller in one kernel): usbgadget (the USB
# haptic interface emulated on FunctionFS with the simulated plant) as one process, the trainer
# (libusb backend) as another, exactly as a trainer and a USB haptic device on a bench.
# Everything lands in $BENCHVM_OUT.
#   usb_trainer_session.sh BIN_DIR SCENE DEVICE PERIOD_US CYCLES SLOW_MOTION [UNPLUG_AFTER_S]
# SLOW_MOTION: both processes run real time slowed by this factor (--slow-motion), as the CAN
# sessions do: the emulator runs the cycle ~20x slower than the hardware. UNPLUG_AFTER_S: write
# "" to the gadget's UDC file (the device disappears from the bus, as when the cable is pulled)
# this many wall seconds after the trainer started.
# Exit status: the trainer's (0 completed, 3 completed with a fault latched), 10 when usbgadget
# failed or the device did not enumerate.
set -uo pipefail
bin=$1 scene=$2 device=$3 period_us=$4 cycles=$5 slow=$6 unplug_after=${7:-}
out=${BENCHVM_OUT:?run me through benchvm run}
gadget_name=trainer_haptic
udc_file=/sys/kernel/config/usb_gadget/$gadget_name/UDC

# The USB stack (dummy_hcd, libcomposite, FunctionFS) is loaded for the tests that ask for it.
if ! tools/benchvm/usb-gadget-modules >"$out/modules.txt" 2>&1; then
  echo "the USB gadget modules did not load:"
  cat "$out/modules.txt"
  exit 10
fi
# The device is separate hardware on a real bench: it gets a real-time priority so that the
# emulated trainer never starves it.
chrt -f 50 "$bin/usbgadget" --scene "$scene" --device "$device" --period-us "$period_us" \
  --slow-motion "$slow" --gadget-name "$gadget_name" --events "$out/usbgadget_events.jsonl" \
  >"$out/usbgadget.txt" 2>&1 &
gadget=$!
. tests/benchvm/usb_gadget_wait.sh
wait_for_gadget "$gadget" "$out/usbgadget.txt" || exit 10
"$bin/trainer" --scene "$scene" --device "$device" --period-us "$period_us" --cycles "$cycles" \
  --slow-motion "$slow" --overrun-streak-limit 1000 --no-rt --report "$out/usb_report.json" \
  >"$out/trainer.txt" 2>&1 &
trainer=$!
if [ -n "$unplug_after" ]; then
  sleep "$unplug_after"
  # Unbind the gadget from its device controller: the host sees a disconnect.
  date +%s.%N >"$out/unplug_time.txt"
  echo "" >"$udc_file"
  echo "unplugged (UDC unbound) at $(cat "$out/unplug_time.txt")"
fi
wait "$trainer"
status=$?
kill -INT "$gadget" 2>/dev/null
wait "$gadget"
gadget_status=$?
cat "$out/trainer.txt"
tail -n 5 "$out/usbgadget.txt"
echo "trainer exit $status, usbgadget exit $gadget_status"
# After an unplug the gadget may report the lost host; only its start-up matters then.
if [ -z "$unplug_after" ] && [ "$gadget_status" -ne 0 ]; then exit 10; fi
exit "$status"
