# Sourced by the bench VM's USB scripts (usb_trainer_session.sh, usb_bench.sh, hil_io.sh) after
# they start usbgadget in the background:
#   wait_for_gadget PID LOG
# waits up to 20 s for the host's usbcore to create the device 1209:0001 in sysfs (the gadget
# enumerated on dummy_hcd). Returns 0 when it did; otherwise prints LOG (the gadget's output),
# stops the gadget and returns 10, the scripts' "the device did not come up" status.
wait_for_gadget() {
  local pid=$1 log=$2 dev
  for _ in $(seq 1 200); do
    for dev in /sys/bus/usb/devices/*; do
      if [ "$(cat "$dev/idVendor" 2>/dev/null)" = 1209 ] &&
         [ "$(cat "$dev/idProduct" 2>/dev/null)" = 0001 ]; then
        return 0
      fi
    done
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  echo "FAIL: the gadget did not enumerate within 20 s"
  cat "$log"
  kill -INT "$pid" 2>/dev/null
  wait "$pid"
  return 10
}
