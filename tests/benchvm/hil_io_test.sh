#!/usr/bin/env bash
# hil's GPIO part (tools/hil/io, run by `hil`) on a real kernel GPIO chip (gpio-sim) in the
# bench VM, one boot (tests/benchvm/hil_io.sh runs the cases, this script judges them):
#  - a good bench: scan passes every [gpio] line; check passes the e-stop and enable
#    edge-to-latch steps over TRIALS presses each and reads the outputs back;
#  - a device file naming a line the chip lacks: scan fails that line, naming it; one naming a
#    line the kernel holds as an output (a hog) as the enable input: used, wrong direction;
#  - a dead e-stop line: check fails gpio.estop.edge_to_latch with "no edge on ... check wiring" (2 s timeout);
#  - USB: usbgadget on dummy_hcd: scan finds it with the device file's identity, check passes the
#    round trip (200 exchanges, x16), a torque pulse per channel and the watchdog; a device file
#    naming another serial fails the scan (missing + extra).
#   hil_io_test.sh SOURCE_DIR BIN_DIR [TRIALS] [SLOW_MOTION] [OUT_DIR]
# TRIALS >= 100 with OUT_DIR is the documented distribution run (docs/hil-io.md):
#   tests/benchvm/hil_io_test.sh . build/release/bin 100 16 /tmp/hil-io-trials
set -euo pipefail
src=$1 bin=$2 trials=${3:-3} slow=${4:-32}
work=${5:-$(mktemp -d)}
[ $# -ge 5 ] || trap 'rm -rf "$work"' EXIT
mkdir -p "$work"
cd "$src"
status=0
only=
[ "$trials" -lt 100 ] || only=gpio-only
for program in "$bin/hil" "$bin/usbgadget"; do
  [ -x "$program" ] || { echo "hil_io_test: $program missing: build hil and usbgadget" >&2; exit 1; }
done
tools/benchvm/benchvm run --gpio-sim --smp 2 --timeout 600 --out "$work" -- \
  tests/benchvm/hil_io.sh "$bin" "$trials" "$slow" $only || status=$?
[ "$status" -ne 77 ] || exit 77
[ "$status" -eq 0 ] || { echo "FAIL: the guest exited with $status"; exit 1; }
python3 - "$work" "$trials" "$only" <<'PY'
import json, os, sys
work, trials, only = sys.argv[1], int(sys.argv[2]), sys.argv[3]
failures = []
def load(name):
    status = int(open(os.path.join(work, name + ".status")).read())
    try:
        report = json.load(open(os.path.join(work, name + ".json")))
        sections = report.get("scans", []) + report.get("checks", [])
    except ValueError:
        print(open(os.path.join(work, name + ".txt")).read())
        raise
    steps = {}
    for s in sections:
        for step in s.get("comparison", []) + s.get("steps", []):
            steps[step["id"]] = step
            print(f"  {name}: {step['outcome']:4} {step['id']}: {step['reason']}")
    return status, steps
def check(what, ok):
    print(f"{'ok  ' if ok else 'FAIL'} {what}")
    if not ok:
        failures.append(what)

status, steps = load("gpio_scan")
check("good bench: scan exits 0", status == 0)
for role in ("estop", "enable", "drive_enable", "fault_lamp"):
    check(f"good bench: gpio.scan.{role} passes", steps.get(f"gpio.scan.{role}", {}).get("outcome") == "pass")
status, steps = load("gpio_check")
check("good bench: check exits 0", status == 0)
for sid in ("gpio.estop.edge_to_latch", "gpio.enable.edge_to_latch", "gpio.drive_enable.output",
            "gpio.fault_lamp.output"):
    check(f"good bench: {sid} passes", steps.get(sid, {}).get("outcome") == "pass")
for sid in ("gpio.estop.edge_to_latch", "gpio.enable.edge_to_latch"):
    st = steps.get(sid, {})
    fig = {f["name"]: f["value"] for f in st.get("figures", [])}
    check(f"{sid}: {trials} trials", fig.get("trials") == trials)
    print(f"FIGURES {sid}: trials {fig.get('trials')} p50 {fig.get('p50')} p90 {fig.get('p90')} "
          f"p99 {fig.get('p99')} max {fig.get('max')} ms (period {fig.get('period')}, limit "
          f"{fig.get('limit')}); reader {st.get('details', {}).get('reader')}; level before event "
          f"{st.get('details', {}).get('level_before_event')}")
if not only:
    status, steps = load("gpio_scan_miswired")
    check("miswired file: scan exits 1", status == 1)
    st = steps.get("gpio.scan.fault_lamp", {})
    check("miswired file: gpio.scan.fault_lamp fails naming the line",
          st.get("outcome") == "fail" and
          st.get("reason", "").startswith("no line named 'fault_lmp' on gpiochip"))
    status, steps = load("gpio_scan_on_hog")
    check("enable on a hog: scan exits 1", status == 1)
    st = steps.get("gpio.scan.enable", {})
    check("enable on a hog: gpio.scan.enable fails as used, wrong direction",
          st.get("outcome") == "fail" and
          ":4 'spare' already used by 'spare-hog' as an output: wrong direction, the device file "
          "wants an input" in st.get("reason", ""))
    status, steps = load("gpio_check_dead")
    check("dead e-stop: check exits 1", status == 1)
    st = steps.get("gpio.estop.edge_to_latch", {})
    check("dead e-stop: gpio.estop.edge_to_latch fails with the wiring reason",
          st.get("outcome") == "fail" and st.get("reason", "").startswith("no edge on gpiochip")
          and ":0 (estop) within 2 s — check wiring (trial 1 of 1)" in st.get("reason", ""))
    check("dead e-stop: the enable step still passes",
          steps.get("gpio.enable.edge_to_latch", {}).get("outcome") == "pass")
    status, steps = load("usb_scan")
    check("usb: scan exits 0", status == 0)
    for sid in ("usb.scan.device", "usb.scan.protocol_version", "usb.scan.firmware_version",
                "usb.scan.channels"):
        check(f"usb: {sid} passes", steps.get(sid, {}).get("outcome") == "pass")
    status, steps = load("usb_check")
    check("usb: check exits 0", status == 0)
    check("usb: usb.round_trip passes", steps.get("usb.round_trip", {}).get("outcome") == "pass")
    polarity = [s for sid, s in steps.items() if sid.endswith(".polarity")]
    check("usb: 10 channels' polarity pass",
          len(polarity) == 10 and all(s["outcome"] == "pass" for s in polarity))
    check("usb: usb.watchdog passes", steps.get("usb.watchdog", {}).get("outcome") == "pass")
    for sid in ("usb.round_trip", "usb.watchdog"):
        fig = {f["name"]: f["value"] for f in steps.get(sid, {}).get("figures", [])}
        print(f"FIGURES {sid}: {fig}")
    status, steps = load("usb_scan_other_serial")
    check("usb, another serial in the file: scan exits 1", status == 1)
    check("usb, another serial: usb.scan.device fails as missing",
          steps.get("usb.scan.device", {}).get("reason", "").startswith(
              "no USB device 1209:0001 serial 'bench-0002'"))
    check("usb, another serial: the gadget is an extra",
          steps.get("usb.scan.extra.usbgadget-0001", {}).get("outcome") == "fail")
sys.exit(1 if failures else 0)
PY
echo PASS
