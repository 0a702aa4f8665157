#!/usr/bin/env bash
# The USB link's figures in short (CI): usbbench against usbgadget in the bench VM over
# FRAMES cycles of 1 ms in real time (default 3000; the 10^5-frame run of docs/usb-host.md is
# the same with 100000, run by hand), the gadget's plant one sub-step per exchange
# (usb_bench.sh). Checks: every cycle ran without a fault, no IN report refused, no transfer
# error, round trips measured for at least a tenth of the cycles (under TCG the bus takes a
# newer OUT report in place of one still waiting: out_superseded), no heap in the cycle loop.
#   usb_bench_test.sh SOURCE_DIR BIN_DIR [FRAMES] [OUT_DIR]
# Exit 77 (skip) when the bench VM cannot run here.
set -euo pipefail
src=$1 bin=$2 frames=${3:-3000}
work=${4:-$(mktemp -d)}
[ $# -ge 4 ] || trap 'rm -rf "$work"' EXIT
mkdir -p "$work"
cd "$src"
status=0
tools/benchvm/benchvm run --smp 2 --timeout 600 --out "$work" -- \
  tests/benchvm/usb_bench.sh "$bin" config/scenes/wall.toml config/devices/usb_benchvm.toml \
  "$frames" 1000 1 || status=$?
[ "$status" -ne 77 ] || exit 77
if [ "$status" -ne 0 ]; then
  echo "FAIL: usbbench exited with $status"
  tail -n 20 "$work/usbgadget.txt" 2>/dev/null || true
  exit 1
fi
python3 - "$work/usbbench.json" "$frames" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
frames = int(sys.argv[2])
failures = []
def check(name, value, ok):
    print(f"{name:<28} {value!s:>14}  {'ok' if ok else 'FAIL'}")
    if not ok:
        failures.append(name)
check("cycles", r["cycles"], r["cycles"] == frames)
check("faults", r["faults"], r["faults"] == "")
check("bad reports", r["bad_reports"], r["bad_reports"] == 0)
check("transfer errors", r["transfer_errors"], r["transfer_errors"] == 0)
check("round trips", r["round_trip_us"]["count"], r["round_trip_us"]["count"] >= frames // 10)
check("heap in loop", r["heap_allocations_in_loop"],
      r["allocation_hooks_installed"] and r["heap_allocations_in_loop"] == 0)
for key in ("missed_frames", "missed_rate", "stale_frames", "late_cycles"):
    print(f"{key:<28} {r[key]!s:>14}  (shown)")
t = r["round_trip_us"]
print(f"round trip us: min {t['min']:.0f} p50 {t['p50']:.0f} p99 {t['p99']:.0f} "
      f"p99.9 {t['p999']:.0f} max {t['max']:.0f}")
sys.exit(1 if failures else 0)
PY
