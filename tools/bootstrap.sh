#!/usr/bin/env bash
# The README's two entry points.
#   tools/bootstrap.sh run   install dependencies, build (release), build the model images the
#                            scene names (modelc build), run the main job: the default scene
#                            on the simulated device (config/scenes/cbd.toml: the scripted
#                            catheter insertion), report in out/
#   tools/bootstrap.sh test  install dependencies, build and pass every test: the release
#                            suite, the ASan+UBSan unit tests, the TSan concurrency tests and
#                            short libFuzzer runs of the CANopen and USB protocols, the model
#                            image loader and the config reader (fuzz preset, clang)
#   tools/bootstrap.sh bench [benchmark args]
#                            install, build, build the cbd and liver images, run the cycle
#                            benchmark (bench_cycle: the whole cycle and each stage of the
#                            reference scenes, compute only; docs/performance.md)
#   tools/bootstrap.sh jitter
#                            install, build, build the scene's model images, run the timing
#                            acceptance test (jitter: the loop with the scene's workload against
#                            cyclictest; default scene cbd, 60 s each side; docs/timing.md)
# Extra arguments after `run` go to the trainer (e.g. --scene FILE --seconds 5), after
# `jitter` to jitter (e.g. --max-ratio 1.5 --mode alongside).
set -euo pipefail
cd "$(dirname "$0")/.."

jobs=$(nproc 2>/dev/null || echo 2)
mode=${1:-}
[ $# -gt 0 ] && shift

# Sets `args` to the given arguments with --scene added (the default scene, cbd) when absent,
# and `scene` to the scene they name.
scene_args() {
  args=("$@")
  scene=config/scenes/cbd.toml
  for ((i = 0; i < ${#args[@]}; ++i)); do
    if [ "${args[$i]}" = "--scene" ] && [ $((i + 1)) -lt ${#args[@]} ]; then scene=${args[$((i + 1))]}; fi
  done
  if [[ " ${args[*]:-} " != *" --scene "* ]]; then args=(--scene "$scene" "${args[@]}"); fi
}

build() {  # build PRESET [TARGET...]
  local preset=$1; shift
  cmake --preset "$preset" >/dev/null
  if [ $# -gt 0 ]; then
    cmake --build --preset "$preset" -j "$jobs" --target "$@"
  else
    cmake --build --preset "$preset" -j "$jobs"
  fi
}

case "$mode" in
  run)
    tools/install-deps.sh
    build release trainer modelc
    mkdir -p out
    scene_args "$@"
    if [[ " ${args[*]:-} " != *" --report "* ]]; then args+=(--report out/report.json); fi
    echo "== modelc build --scene $scene"
    build/release/bin/modelc build --scene "$scene" --report out/models.json
    echo "== trainer ${args[*]}"
    exec build/release/bin/trainer --hal sim "${args[@]}"
    ;;
  bench)
    tools/install-deps.sh
    build release bench_cycle modelc
    mkdir -p out
    for scene in config/scenes/cbd.toml config/scenes/liver.toml; do
      echo "== modelc build --scene $scene"
      build/release/bin/modelc build --scene "$scene" --report "out/models_$(basename "$scene" .toml).json"
    done
    echo "== bench_cycle $*"
    exec build/release/bench/bench_cycle "$@"
    ;;
  jitter)
    tools/install-deps.sh
    build release jitter modelc
    mkdir -p out
    scene_args "$@"
    echo "== modelc build --scene $scene"
    build/release/bin/modelc build --scene "$scene" --report out/models.json
    echo "== jitter ${args[*]}"
    exec build/release/bin/jitter "${args[@]}"
    ;;
  test)
    tools/install-deps.sh
    echo "== release build and full test suite"
    build release
    ctest --preset release -j "$jobs"
    echo "== ASan+UBSan build: unit tests"
    build asan
    ctest --preset asan -j "$jobs"
    echo "== TSan build: concurrency tests"
    build tsan concurrency_tests
    ctest --preset tsan -j "$jobs"
    echo "== fuzz build (clang, ASan+UBSan): libFuzzer targets, 200,000 runs each (fuzz_config 20,000)"
    build fuzz fuzz_targets
    # One libFuzzer process per target, single-threaded, fixed -runs and -seed: two at a time
    # on two cores give the same results in about half the time.
    ctest --preset fuzz -j "$jobs"
    echo "== all test suites passed"
    ;;
  *)
    echo "usage: tools/bootstrap.sh run [trainer args...] | test | bench [benchmark args...] | jitter [jitter args...]" >&2
    exit 2
    ;;
esac
