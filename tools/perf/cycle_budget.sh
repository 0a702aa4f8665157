#!/usr/bin/env bash
# The 20 µs cycle budget (issue 19), measured reproducibly: the reference scene (cbd: duct +
# catheter + two forceps) in simulated time, the same deterministic session run N times, at
# 1 kHz and at 10 kHz (loop period 100 µs); per cycle the minimum over the runs of the real-clock
# compute time (step, each stage, each sub-stage), and its p50/p99/p99.9/max/mean printed as a
# markdown table (docs/performance.md "The 20 µs cycle (issue 19)" says why the minimum).
# Optionally (--jitter SECONDS, as root) the real-time runs too: `jitter` at 1 kHz and 10 kHz,
# the ratio of the trainer's wake-up latency to cyclictest's, overruns, and whether a fault
# latched.
#
# usage: tools/perf/cycle_budget.sh [--runs N] [--build DIR] [--out DIR] [--no-fifo]
#                                   [--jitter SECONDS]
#   --runs N        runs per period (default 5: with 3, a cycle that noise hit in every run
#                   still reached the 1 kHz p99.9 rank in about one session of four on this VM;
#                   docs/performance.md "After round 5"; more on a busy machine)
#   --build DIR     the release build (default build/release)
#   --out DIR       reports and tables (default out/cycle_budget)
#   --no-fifo       do not run the trainer under SCHED_FIFO (chrt -f 50; root only): other
#                   processes on the machine then preempt it and more runs are needed
#   --jitter S      also run jitter for S seconds per side at 1 kHz and at 10 kHz (root)
#   --table-only    run nothing: print the table again from OUT's reports (with --jitter S
#                   to include OUT's jitter runs)
#   --baseline DIR  also print "before → after" (p50, p99.9) against an earlier OUT (the
#                   before table's runs), row by row
# Writes OUT/cbd-1khz.json, OUT/cbd-10khz.json (trainer reports with the "compute" section),
# OUT/cbd-1khz.csv, OUT/cbd-10khz.csv (the per-cycle minimum of every cycle, ns: which cycles
# are slow, and in which sub-stage), OUT/table.md (the table, then per rate the slowest cycles
# down to the p99.9 rank with their largest sub-stages: what sets the tail), and with --jitter
# OUT/jitter-1khz/, OUT/jitter-10khz/ (jitter's output).
set -euo pipefail

runs=5
build=build/release
out=out/cycle_budget
fifo=1
jitter_seconds=0
table_only=0
baseline=
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --no-fifo) fifo=0; shift ;;
    --jitter) jitter_seconds=$2; shift 2 ;;
    --table-only) table_only=1; shift ;;
    --baseline) baseline=$2; shift 2 ;;
    -h|--help) sed -n '2,28p' "$0"; exit 0 ;;
    *) echo "cycle_budget.sh: unknown argument '$1' (--help)" >&2; exit 2 ;;
  esac
done

repo=$(cd "$(dirname "$0")/../.." && pwd)
cd "$repo"
trainer=$build/bin/trainer
scene=config/scenes/cbd.toml
[ -x "$trainer" ] || { echo "cycle_budget.sh: no $trainer: cmake --build --preset release --target trainer modelc" >&2; exit 1; }
if [ "$jitter_seconds" != 0 ] && [ "$table_only" = 0 ] && [ ! -x "$build/bin/jitter" ]; then
  echo "cycle_budget.sh: no $build/bin/jitter: cmake --build --preset release --target jitter" >&2
  exit 1
fi
if [ ! -f out/models/duct.img ] || [ ! -f out/models/catheter_cbd.img ]; then
  "$build/bin/modelc" build --scene "$scene"
fi
mkdir -p "$out"

# SCHED_FIFO keeps the other processes of a shared machine off the trainer's CPU while it runs
# (the hypervisor's interrupts remain: the per-cycle minimum removes those).
prefix=()
if [ "$fifo" = 1 ]; then
  if [ "$(id -u)" = 0 ] && command -v chrt >/dev/null; then
    prefix=(chrt -f 50)
  else
    echo "cycle_budget.sh: not root (or no chrt): running under SCHED_OTHER" >&2
    fifo=0
  fi
fi

# The revision the binaries were built from: the build tree's source checkout (a --build in
# another worktree), else this checkout for the default build, else "binaries of DIR".
source_dir=$(sed -n 's/^CMAKE_HOME_DIRECTORY:INTERNAL=//p' "$build/CMakeCache.txt" 2>/dev/null || true)
if [ -n "$source_dir" ]; then
  revision=$(git -C "$source_dir" describe --always --dirty 2>/dev/null || echo unknown)
elif [ "$build" = build/release ]; then
  revision=$(git describe --always --dirty 2>/dev/null || echo unknown)
else
  revision="binaries of $build"
fi
if [ "$table_only" = 0 ]; then
  printf '{"utc": "%s", "revision": "%s", "load": "%s", "runs": %s, "fifo": %s}\n' \
    "$(date -u '+%Y-%m-%d %H:%M UTC')" "$revision" \
    "$(cut -d' ' -f1-3 /proc/loadavg)" "$runs" "$fifo" >"$out/run_info.json"
fi
for period in 1000 100; do
  [ "$table_only" = 0 ] || break
  name=cbd-$((1000 / period))khz
  echo "cycle_budget.sh: $name: $runs runs of the scripted session, simulated time" >&2
  status=0
  "${prefix[@]}" "$trainer" --scene "$scene" --hal sim --time simulated --period-us "$period" \
    --repeat "$runs" --report "$out/$name.json" --compute-csv "$out/$name.csv" \
    >"$out/$name.txt" 2>"$out/$name.log" || status=$?
  if [ "$status" -ne 0 ]; then
    echo "cycle_budget.sh: trainer exited with $status ($out/$name.txt, $out/$name.log)" >&2
    cat "$out/$name.txt" "$out/$name.log" >&2
    exit 1
  fi
done

if [ "$jitter_seconds" != 0 ] && [ "$table_only" = 0 ]; then
  for period in 1000 100; do
    name=jitter-$((1000 / period))khz
    echo "cycle_budget.sh: $name: jitter, real time, $jitter_seconds s per side" >&2
    status=0
    "$build/bin/jitter" --scene "$scene" --period-us "$period" --seconds "$jitter_seconds" \
      --out "$out/$name" >"$out/$name.txt" 2>&1 || status=$?
    # 3 = a run latched a fault: measured, reported below.
    if [ "$status" -ne 0 ] && [ "$status" -ne 3 ]; then
      echo "cycle_budget.sh: jitter exited with $status ($out/$name.txt)" >&2
      cat "$out/$name.txt" >&2
      exit 1
    fi
  done
fi

python3 - "$out" "$jitter_seconds" "$baseline" >"$out/table.md" <<'PY'
import json, os, sys
out, jitter_seconds, baseline = sys.argv[1:4]
def load_reports(directory):
    return {label: json.load(open(os.path.join(directory, f"cbd-{label}.json")))
            for label in ("1khz", "10khz")}
reports = load_reports(out)
us = lambda ns: f"{ns / 1000:.1f}"
first = reports["1khz"]["compute"]
info = json.load(open(os.path.join(out, "run_info.json")))
print(f"cbd, simulated time, per-cycle minimum of {info['runs']} identical runs, real clock (µs); "
      f"{info['utc']}, {info['revision']}, {os.cpu_count()} CPUs, load {info['load']}, "
      f"{'SCHED_FIFO 50' if info['fifo'] == 1 else 'SCHED_OTHER'}")
print()
for label, report in reports.items():
    c = report["compute"]
    if not c["identical"]:
        print(f"**WARNING: the {label} runs were not identical: {c['mismatch']}**")
    print(f"- {label}: {c['cycles']} cycles of {c['period_ns'] / 1000:.0f} µs; each run's own step "
          "p50/p99.9: " + ", ".join(f"{us(r['step_ns']['p50'])}/{us(r['step_ns']['p99_9'])}"
                                   for r in c["per_run"]))
print()
print("| µs | 1 kHz p50 | p99 | p99.9 | max | mean | 10 kHz p50 | p99 | p99.9 | max | mean |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
# Cycle order (the JSON objects' keys come sorted by name).
stage_order = ["hal_read", "kinematics", "modal_models", "tensor_models", "catheters", "forces",
               "hal_write", "publish"]
substage_order = {"modal_models": ["modal_near", "modal_collision", "modal_solve", "modal_step",
                                   "modal_reconstruct", "modal_refit"],
                  "catheters": ["catheter_walls", "catheter_tools", "catheter_step",
                                "catheter_reactions"]}
def rows():
    c = first
    yield "**step**", "step_ns", None
    for stage in stage_order:
        if stage not in c["stages_ns"]:
            continue
        yield stage, "stages_ns", stage
        for sub in substage_order.get(stage, []):
            if sub in c["substages_ns"]:
                yield "&nbsp;&nbsp;" + sub, "substages_ns", sub
for label, section, key in rows():
    cells = []
    for report in reports.values():
        s = report["compute"][section] if key is None else report["compute"][section].get(key)
        if s is None:
            cells += ["–"] * 5
        else:
            cells += [us(s["p50"]), us(s["p99"]), us(s["p99_9"]), us(s["max"]), us(s["mean"])]
    if key is None:
        cells = [f"**{c}**" for c in cells]
    print(f"| {label} | " + " | ".join(cells) + " |")
if baseline:
    before = load_reports(baseline)
    before_info = json.load(open(os.path.join(baseline, "run_info.json")))
    print()
    print(f"Before ({baseline}: {before_info['utc']}, {before_info['revision']}, load "
          f"{before_info['load']}) → after (above), per-cycle minimum, µs:")
    print()
    print("| µs | 1 kHz p50 | 1 kHz p99.9 | 10 kHz p50 | 10 kHz p99.9 |")
    print("|---|---|---|---|---|")
    for label, section, key in rows():
        cells = []
        for rate in ("1khz", "10khz"):
            for q in ("p50", "p99_9"):
                def value(reports_):
                    c = reports_[rate]["compute"]
                    s = c[section] if key is None else c[section].get(key)
                    return None if s is None else s[q]
                b, a = value(before), value(reports)
                if b is None or a is None:
                    cells.append(f"{us(b) if b is not None else '–'} → {us(a) if a is not None else '–'}")
                else:
                    cells.append(f"{us(b)} → {us(a)} ({a / b - 1:+.0%})" if b > 0 else f"{us(b)} → {us(a)}")
        print(f"| {label} | " + " | ".join(cells) + " |")
# Which cycles set the tail: the slowest cycles of each rate down to the p99.9 rank (the
# per-cycle CSV), each with its three largest sub-stages, and how many of the p99.9 set each
# sub-stage leads.
import csv, math
substages = [s for subs in substage_order.values() for s in subs] + ["hal_read", "kinematics", "forces",
                                                                     "hal_write", "publish"]
for label in ("1khz", "10khz"):
    path = os.path.join(out, f"cbd-{label}.csv")
    if not os.path.exists(path):
        continue
    cycles = list(csv.DictReader(open(path)))
    if not cycles:
        continue
    cycles.sort(key=lambda row: -float(row["step"]))
    rank = max(1, math.ceil(0.001 * len(cycles)))
    leaders = {}
    for row in cycles[:rank]:
        lead = max((k for k in substages if k in row), key=lambda k: float(row[k]))
        leaders[lead] = leaders.get(lead, 0) + 1
    print()
    print(f"{label}: the {rank} slowest cycles (p99.9 = the {rank}th) lead by "
          + ", ".join(f"{k} {n}" for k, n in sorted(leaders.items(), key=lambda kv: -kv[1])) + "; the "
          + f"{min(rank, 12)} slowest:")
    print()
    print("| cycle | step µs | largest sub-stages (µs) |")
    print("|---|---|---|")
    for row in cycles[:min(rank, 12)]:
        top = sorted((k for k in substages if k in row), key=lambda k: -float(row[k]))[:3]
        print(f"| {row['cycle']} | {us(float(row['step']))} | " + ", ".join(f"{k} {us(float(row[k]))}" for k in top) + " |")
if jitter_seconds != "0":
    print()
    print(f"Real time (`jitter`, {jitter_seconds} s per side, one after the other, SCHED_FIFO 80 on CPU 1):")
    print()
    print("| run | trainer wake p99 / p99.9 µs | cyclictest p99 / p99.9 µs | ratio p99 / p99.9 | "
          "step p50 / p99.9 µs | overruns | longest streak | fault latched |")
    print("|---|---|---|---|---|---|---|---|")
    f1 = lambda v: f"{v:.1f}"
    f2 = lambda v: f"{v:.2f}"
    for label in ("1khz", "10khz"):
        path = os.path.join(out, f"jitter-{label}", "summary.json")
        if not os.path.exists(path):
            print(f"| cbd {label} | no summary (see {out}/jitter-{label}.txt) | | | | | | |")
            continue
        j = json.load(open(path))
        t, ct, ratio = j["trainer"], j["cyclictest"]["latency_us"], j["ratio_trainer_over_cyclictest"]
        faults = []
        for run in t["run_list"]:
            if run["faults_latched"]:
                r = json.load(open(os.path.join(out, f"jitter-{label}", run["report"])))
                faults.append(f"{run['first_fault']} at cycle {r['safety']['first_fault_cycle']}")
        print(f"| cbd {label} | {f1(t['wake_latency_us']['p99'])} / {f1(t['wake_latency_us']['p99_9'])} | "
              f"{f1(ct['p99'])} / {f1(ct['p99_9'])} | {f2(ratio['p99'])} / {f2(ratio['p99_9'])} | "
              f"{f1(t['step_time_us']['p50'])} / {f1(t['step_time_us']['p99_9'])} | "
              f"{t['overruns']} of {t['cycles']} | {t['longest_overrun_streak']} | "
              f"{'; '.join(faults) if faults else 'no'} ({t['faulted_runs']} of {t['runs']} runs) |")
PY
cat "$out/table.md"
