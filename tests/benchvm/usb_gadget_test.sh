#!/usr/bin/env bash
# The USB haptic interface over a real kernel USB stack: in the bench VM, tools/usbgadget
# (FunctionFS, bound to dummy_hcd's UDC) enumerates at high speed and usb_probe (libusb) checks
# descriptors, identity, 1,000 OUT->IN round trips, 2,000 periods of 2 ms with transfers in
# flight (paced: no transfer or decode error allowed; missed frames reported, not judged: TCG)
# and the device watchdog (usb_session.sh).
#   usb_gadget_test.sh SOURCE_DIR BIN_DIR PROBE [OUT_DIR]
# Exit 77 (skip) when the bench VM cannot run here.
set -euo pipefail
src=$1 bin=$2 probe=$3
for program in "$bin/usbgadget" "$probe"; do
  [ -x "$program" ] || { echo "usb_gadget_test: $program missing: build usbgadget and usb_probe first" >&2; exit 1; }
done
work=${4:-$(mktemp -d)}
[ $# -ge 4 ] || trap 'rm -rf "$work"' EXIT
mkdir -p "$work"
cd "$src"
status=0
tools/benchvm/benchvm run --timeout 80 --out "$work" -- \
  tests/benchvm/usb_session.sh "$bin" "$probe" --exchanges 1000 --paced-frames 2000 --period-us 2000 || status=$?
[ "$status" -ne 77 ] || exit 77
[ "$status" -eq 0 ] || { echo "FAIL: the USB session exited with $status"; exit 1; }
cat "$work/probe.json"
