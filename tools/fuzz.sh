#!/usr/bin/env bash
# Long libFuzzer runs of the CANopen and USB protocol libraries, the model image loader and the
# configuration reader (tests/fuzz, docs/fuzzing.md).
#   tools/fuzz.sh [TARGET|all] [RUNS]
# TARGET: fuzz_can_frames, fuzz_sdo_client, fuzz_usb_in_report, fuzz_model_image, fuzz_config or
# all (default); RUNS: executions per target (default 10,000,000). FUZZ_MAX_SECONDS, when set,
# also stops each target after that many seconds (libFuzzer's -max_total_time; the figures are
# then of the executions reached). fuzz_model_image and fuzz_config get the options their ctest
# runs use (-max_len, -timeout, fuzz_config's -dict=tests/fuzz/config.dict). Configures and builds the `fuzz` preset (clang, ASan+UBSan; only the
# fuzz targets), then runs each target from its seed corpus (tests/fuzz/corpus/TARGET, read
# only) plus the corpus it grows in build/fuzz/tests/fuzz/corpus/TARGET, and prints
# executions, wall time and exec/s. A crash stops that target, keeps the input under
# build/fuzz/tests/fuzz/artifacts/TARGET/ and makes the script exit 1.
# FUZZ_JOBS sets the build's parallel jobs (default 2).
set -euo pipefail
cd "$(dirname "$0")/.."

target=${1:-all}
runs=${2:-10000000}
all_targets=(fuzz_can_frames fuzz_sdo_client fuzz_usb_in_report fuzz_model_image fuzz_config)
if [ "$target" = all ]; then
  targets=("${all_targets[@]}")
elif [[ " ${all_targets[*]} " == *" $target "* ]]; then
  targets=("$target")
else
  echo "usage: tools/fuzz.sh [fuzz_can_frames|fuzz_sdo_client|fuzz_usb_in_report|fuzz_model_image|fuzz_config|all] [RUNS]" >&2
  exit 2
fi
if ! [[ "$runs" =~ ^[0-9]+$ ]] || [ "$runs" -lt 1 ]; then
  echo "tools/fuzz.sh: RUNS must be a positive integer, got '$runs'" >&2
  exit 2
fi

cmake --preset fuzz >/dev/null
cmake --build --preset fuzz -j "${FUZZ_JOBS:-2}" --target fuzz_targets

status=0
for t in "${targets[@]}"; do
  work=build/fuzz/tests/fuzz/corpus/$t
  artifacts=build/fuzz/tests/fuzz/artifacts/$t
  log=build/fuzz/tests/fuzz/$t.log
  mkdir -p "$work" "$artifacts"
  options=()
  case $t in
    fuzz_model_image) options=(-max_len=16384 -timeout=10) ;;
    fuzz_config) options=(-max_len=16384 -timeout=10 -dict=tests/fuzz/config.dict) ;;
  esac
  if [ -n "${FUZZ_MAX_SECONDS:-}" ]; then options+=(-max_total_time="$FUZZ_MAX_SECONDS"); fi
  echo "== $t: $runs executions (log $log)"
  start=$(date +%s.%N)
  set +e
  "build/fuzz/tests/fuzz/$t" -runs="$runs" -print_final_stats=1 -artifact_prefix="$artifacts/" "${options[@]}" \
    "$work" "tests/fuzz/corpus/$t" >"$log" 2>&1
  rc=$?
  set -e
  end=$(date +%s.%N)
  executed=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=""
  coverage=$(grep -oE 'cov: [0-9]+ ft: [0-9]+' "$log" | tail -1 || true)
  corpus=$(find "$work" -type f | wc -l)
  seconds=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.1f", b - a }')
  # libFuzzer's own average is whole executions per second of its run (0 under a second).
  if [ -n "$executed" ]; then rate=$(awk -v n="$executed" -v s="$seconds" 'BEGIN { printf "%.0f", (s > 0) ? n / s : 0 }'); fi
  if [ "$rc" -eq 0 ]; then
    echo "$t: ${executed:-?} executions in $seconds s (${rate:-?} exec/s), $coverage, corpus $corpus inputs: no crash"
  else
    echo "$t: FAILED (exit $rc) after $seconds s; input kept in $artifacts/; see $log" >&2
    grep -E 'ERROR|SUMMARY|#[0-9]+ .* in .*(canopen|usbproto|model|config|fuzz_)' "$log" | head -20 >&2 || true
    status=1
  fi
done
exit $status
