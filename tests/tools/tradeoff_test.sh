#!/usr/bin/env bash
# The speed/accuracy tools end to end: `tradeoff --quick` on the cbd scene writes its CSV, plot
# and recommendations; `modelc build --error-budget` picks a mode count, records the budget and
# the measured error in the image, and the trainer loads that image and runs with it.
# usage: tradeoff_test.sh TRADEOFF MODELC TRAINER SOURCE_DIR
set -euo pipefail
tradeoff=$1
modelc=$2
trainer=$3
source_dir=$4
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp -r "$source_dir/config" "$work/config"   # images land in $work/out
scene="$work/config/scenes/cbd.toml"

"$tradeoff" --scene "$scene" --quick --only duct --out "$work/trade" >"$work/trade.txt" 2>&1 ||
  { echo "tradeoff failed"; cat "$work/trade.txt"; exit 1; }
test -s "$work/trade/cbd/duct.png" || { echo "no plot"; cat "$work/trade.txt"; exit 1; }

"$modelc" build --scene "$scene" --only duct --error-budget 10 --report "$work/build.json" \
  >"$work/build.txt" 2>&1 || { echo "modelc failed"; cat "$work/build.txt"; exit 1; }
# The scene's catheter image too (the trainer runs every model from its image).
"$modelc" build --scene "$scene" --only catheter >"$work/catheter.txt" 2>&1 \
  || { echo "modelc (catheter) failed"; cat "$work/catheter.txt"; exit 1; }
"$trainer" --scene "$scene" --hal sim --time simulated --cycles 2000 --report "$work/run.json" \
  >"$work/run.txt" 2>&1 || { echo "trainer failed"; cat "$work/run.txt"; exit 1; }

# A budget no mode count meets at the definition's time step: refused, naming the budget, the
# best candidate and what else would meet it; the image built above is left as it was.
image="$work/out/models/duct.img"
before=$(sha256sum "$image")
if "$modelc" build --scene "$scene" --only duct --error-budget 1 >"$work/refused.txt" 2>&1; then
  echo "an unreachable budget was accepted"; cat "$work/refused.txt"; exit 1
fi
for fragment in "no configuration meets the error budget 1.000 %" "the most accurate" \
                "time_step_s = 1.000 ms" "loop.period_us"; do
  grep -qF "$fragment" "$work/refused.txt" ||
    { echo "refusal does not say '$fragment'"; cat "$work/refused.txt"; exit 1; }
done
test "$(sha256sum "$image")" = "$before" || { echo "a refused build changed the image"; exit 1; }

python3 - "$work/trade/cbd" "$work/build.json" "$work/run.json" <<'PY'
import csv, json, sys
directory, build_path, run_path = sys.argv[1:4]
rows = list(csv.DictReader(open(f"{directory}/duct.csv")))
assert len(rows) >= 8, len(rows)
for row in rows:
    assert float(row["cost_median_ns"]) > 0 and float(row["cost_p99_ns"]) >= float(row["cost_median_ns"]), row
    assert 0 <= float(row["worst_error"]) < float("inf"), row
by = {(int(r["modes"]), r["static_correction"], r["element"], r["time_step_us"]): r for r in rows}
# Static correction is what makes displacement-driven contact on few modes usable.
assert float(by[(10, "0", "dkt", "1000")]["worst_error"]) > 10 * float(by[(10, "1", "dkt", "1000")]["worst_error"])
scenarios = list(csv.DictReader(open(f"{directory}/duct_scenarios.csv")))
assert len(scenarios) == 5 * len(rows), (len(scenarios), len(rows))
assert {s["tuning"] for s in scenarios} == {"0", "1"}
summary = json.load(open(f"{directory}/summary.json"))
duct = summary["models"][0]
assert duct["name"] == "duct" and duct["pareto_front"], duct.keys()
assert any(r["met"] for r in duct["recommendations"]), duct["recommendations"]

build = json.load(open(build_path))
model = build["models"][0]
budget = model["error_budget"]
assert budget["budget"] == 0.10, budget
assert budget["tuning_error"] <= 0.10 and budget["validation_error"] <= 0.10, budget
assert model["mode_count"] == budget["chosen_mode_count"], (model["mode_count"], budget)
cheaper = [c for c in budget["candidates"] if c["selection_cost_ns"] < budget["selection_cost_ns"] / 1.05]
assert all(c["tuning_error"] > 0.10 or c["validation_error"] > 0.10 for c in cheaper), cheaper

run = json.load(open(run_path))
loaded = run["models"][0]
assert loaded["name"] == "duct" and loaded["mode_count"] == model["mode_count"], loaded
assert run["memory"]["heap_allocations_after_arming"] == 0
print(f"tradeoff: {len(rows)} configurations; budget 10 %: r = {model['mode_count']}, "
      f"static correction {model['static_correction']}, error {100 * budget['measured_error']:.2f} %; "
      f"trainer ran it")
PY
