#!/usr/bin/env bash
# Runs inside the bench VM: usbgadget (the emulated USB haptic interface) and usbbench (the
# trainer's libusb backend in a bare cycle loop) as two processes; usbbench measures the round
# trip OUT -> device -> IN and the missed frames over FRAMES cycles of PERIOD_US
# (docs/usb-host.md).
#   usb_bench.sh BIN_DIR SCENE DEVICE FRAMES PERIOD_US SLOW_MOTION
# Exit status: usbbench's (0 done, 1 setup failed, 3 a fault latched), 10 when the device did
# not enumerate.
set -uo pipefail
bin=$1 scene=$2 device=$3 frames=$4 period_us=$5 slow=$6
out=${BENCHVM_OUT:?run me through benchvm run}
# The USB stack (dummy_hcd, libcomposite, FunctionFS) is loaded for the tests that ask for it.
if ! tools/benchvm/usb-gadget-modules >"$out/modules.txt" 2>&1; then
  echo "the USB gadget modules did not load:"
  cat "$out/modules.txt"
  exit 10
fi
# The gadget's plant advances one sub-step (100 us) per exchange: under TCG the plant's
# integration, not the link, limited the exchanges to ~3,600 plant sub-steps a second (~360
# exchanges/s at 1 ms of plant time per exchange, ~90/s at 4 ms); the link's figures need a
# device that answers at once, as a real interface's firmware does.
chrt -f 50 "$bin/usbgadget" --scene "$scene" --device "$device" --period-us 100 \
  --slow-motion "$slow" >"$out/usbgadget.txt" 2>&1 &
gadget=$!
. tests/benchvm/usb_gadget_wait.sh
wait_for_gadget "$gadget" "$out/usbgadget.txt" || exit 10
chrt -f 40 "$bin/usbbench" --device "$device" --frames "$frames" --period-us "$period_us" \
  --slow-motion "$slow" --report "$out/usbbench.json"
status=$?
kill -INT "$gadget" 2>/dev/null
wait "$gadget"
tail -n 3 "$out/usbgadget.txt"
exit "$status"
