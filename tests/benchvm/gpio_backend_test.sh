#!/usr/bin/env bash
# The GPIO backend against a real kernel GPIO chip (gpio-sim) in the bench VM, judged here.
#   gpio_backend_test.sh SOURCE_DIR BIN_DIR smoke
#   gpio_backend_test.sh SOURCE_DIR BIN_DIR lines [PRESSES] [PERIOD_US]   (smoke checks included)
set -euo pipefail
src=$1 bin=$2 what=$3 presses=${4:-1000} period_us=${5:-4000}
cd "$src"
log=$(mktemp)
trap 'rm -f "$log"' EXIT
status=0
tools/benchvm/benchvm run --gpio-sim --smp 2 --timeout 240 -- \
  tests/benchvm/gpio_backend.sh "$bin" "$what" "$presses" "$period_us" | tee "$log" || status=$?
[ "$status" -ne 77 ] || exit 77
fail() { echo "FAIL: $*"; exit 1; }
expect() { grep -qF -- "$1" "$log" || fail "expected in the guest's output: $1"; }
expect "line 0: 'estop' unused input"
expect "line 2: 'drive_enable' unused input"
expect "line 5: 'hogged' hogged-hog output"
expect "estop through libgpiod: 0, after pull-up 1, after pull-down 0"
case "$what" in
  lines)
    expect "by-name: ok"
    expect "by-offset: ok"
    expect "missing-chip: error: vm: gpio.input[0]: chip 'no-such-chip' line 'estop': no such GPIO chip"
    expect "missing-line: error: vm: gpio.input[0]: chip 'trainer-bench' line 'estopp' (gpiochip"
    expect "'trainer-bench'): no line of that name on the chip"
    expect "missing-offset: error: vm: gpio.output[0]: chip 'trainer-bench' line 99 (gpiochip"
    expect "same-line-twice: error: vm: gpio.output[0]: chip 'trainer-bench' line 0 (gpiochip"
    expect "the same line as gpio.input[0]"
    expect "hog-as-input: error: vm: gpio.input[0]: chip 'trainer-bench' line 'hogged' (gpiochip"
    expect "already used by 'hogged-hog' as an output"
    expect "used-line: error: vm: gpio.input[0]: chip 'trainer-bench' line 'estop' (gpiochip"
    expect "already used by 'other-program' as an input"
    expect "after-release: ok"
    expect "drive_enable after the configure cases (released, back to its pull): 0"
    line=$(grep -a '^presses ' "$log") || fail "no press figures"
    read -r _ n _ latched _ within _ latched_within _ <<<"$line"
    [ "$latched" = "$n" ] || fail "presses $n, latched $latched"
    [ "$within" -ge "$presses" ] && [ "$latched_within" = "$within" ] \
      || fail "presses within one period $within (latched $latched_within), wanted $presses"
    [[ $line == *"heap_allocations_in_reader 0"* ]] || fail "heap in the reading thread: $line"
    [[ $line == *"read_errors 0 "* ]] || fail "read errors: $line"
    ;;
esac
[ "$status" -eq 0 ] || fail "the guest exited with $status"
echo "PASS"
