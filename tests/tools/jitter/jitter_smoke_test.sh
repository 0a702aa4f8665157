#!/usr/bin/env bash
# The jitter program end to end against the real cyclictest, kept short (about 4 s): the wall
# scene for 1 s sequential, then 0.5 s alongside with an acceptance limit no run can meet and
# gnuplot pointed at a missing program. Checked: every file is written, the JSON agrees with the
# CSV histograms (sample counts, percentiles recomputed from the bins, ratios), the modes and
# CPUs are as documented, the acceptance failure gives exit 4 and names the percentile, a
# missing gnuplot is reported while everything else is still written, and setup errors
# (missing cyclictest, an override out of range) give exit 1 with a message.
# usage: jitter_smoke_test.sh JITTER SOURCE_DIR
# Exit 77 (ctest: skipped) when cyclictest cannot get real-time scheduling here.
set -euo pipefail
jitter=$1
source_dir=$2
if ! command -v cyclictest >/dev/null; then
  echo "cyclictest not found: it is a declared dependency (Debian rt-tests, tools/install-deps.sh)"
  exit 1
fi
if [ "$(id -u)" -ne 0 ] && [ "$(ulimit -r)" = "0" ]; then
  echo "SKIP: cyclictest needs root or an RLIMIT_RTPRIO above 0 (ulimit -r is 0 for $(id -un))"
  exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene="$source_dir/config/scenes/wall.toml"
cpus=$(nproc)
cpu=$((cpus - 1))  # the scene's cpu 1 may not exist on a one-CPU runner

"$jitter" --scene "$scene" --seconds 1 --cpu "$cpu" --out "$work/seq" >"$work/seq.txt" 2>&1 \
  || { echo "jitter (sequential) failed"; cat "$work/seq.txt"; exit 1; }

set +e
"$jitter" --scene "$scene" --seconds 0.5 --cpu "$cpu" --mode alongside --max-ratio 0.001 \
  --gnuplot /nonexistent/gnuplot --out "$work/along" >"$work/along.txt" 2>&1
along_status=$?
"$jitter" --scene "$scene" --seconds 0.5 --cyclictest /nonexistent/cyclictest \
  --out "$work/missing" >"$work/missing.txt" 2>&1
missing_status=$?
"$jitter" --scene "$scene" --seconds 0.5 --period-us 20 --out "$work/bad" >"$work/bad.txt" 2>&1
bad_status=$?
set -e
[ "$along_status" -eq 4 ] || { echo "alongside: exit $along_status, expected 4"; cat "$work/along.txt"; exit 1; }
[ "$missing_status" -eq 1 ] && grep -q "rt-tests" "$work/missing.txt" \
  || { echo "missing cyclictest: exit $missing_status"; cat "$work/missing.txt"; exit 1; }
[ "$bad_status" -eq 1 ] && grep -q "loop.period_us = 20 is out of range" "$work/bad.txt" \
  || { echo "bad period: exit $bad_status"; cat "$work/bad.txt"; exit 1; }

python3 - "$work" "$cpu" "$cpus" <<'PY'
import json, math, os, shutil, sys
work, cpu, cpus = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])

def histogram(path):
    rows = open(path).read().splitlines()
    assert rows[0] == "lower_us,upper_us,count", rows[0]
    bins = [tuple(float(x) for x in row.split(",")) for row in rows[1:]]
    for (lo, up, n), nxt in zip(bins, bins[1:] + [None]):
        assert lo < up and n > 0, (lo, up, n)
        assert nxt is None or nxt[0] >= up, (up, nxt)
    return bins

def percentile(bins, largest, fraction):  # docs/timing.md: upper edge of the rank's bin
    total = sum(n for _, _, n in bins)
    rank = min(max(math.ceil(fraction * total), 1), total)
    seen = 0
    for _, up, n in bins:
        seen += n
        if seen >= rank:
            return min(up, largest)

def check(directory, mode, expect_plot):
    s = json.load(open(os.path.join(directory, "summary.json")))
    for name in ("trainer_wake_latency.csv", "trainer_step_time.csv", "cyclictest_latency.csv",
                 "cyclictest_histogram.txt", "cyclictest_output.txt", "trainer_run_1.json",
                 "jitter_plot.dat", "jitter.gp"):
        assert os.path.getsize(os.path.join(directory, name)) > 0, name
    assert s["mode"] == mode, s["mode"]
    assert s["scene"]["name"] == "wall"
    assert s["settings"]["period_us"] == 1000.0 and s["settings"]["priority"] == 80, s["settings"]
    assert s["settings"]["cpu"] == cpu, s["settings"]
    assert s["host"]["kernel_release"] == os.uname().release, s["host"]
    t, c = s["trainer"], s["cyclictest"]
    assert t["cycles"] == s["settings"]["target_cycles"] == sum(r["cycles"] for r in t["run_list"]), t
    assert t["runs"] == len(t["run_list"]) == 1, t["runs"]
    assert t["heap_allocations_after_arming"] == 0, t
    assert t["rt"]["policy"] == "SCHED_FIFO" and t["rt"]["cpu"] == cpu, t["rt"]
    assert c["exit_status"] == 0, c
    assert "-i1000" in c["command"].split() and "-p80" in c["command"].split(), c["command"]
    wake = histogram(os.path.join(directory, "trainer_wake_latency.csv"))
    cyc = histogram(os.path.join(directory, "cyclictest_latency.csv"))
    assert sum(n for *_, n in wake) == t["wake_latency_us"]["count"] == t["cycles"]
    assert sum(n for *_, n in cyc) == c["latency_us"]["count"] == c["loops"]
    for side, bins in ((t["wake_latency_us"], wake), (c["latency_us"], cyc)):
        assert side["p50"] <= side["p90"] <= side["p99"] <= side["p99_9"] <= side["max"], side
        for key, fraction in (("p50", 0.5), ("p90", 0.9), ("p99", 0.99), ("p99_9", 0.999)):
            expected = percentile(bins, side["max"], fraction)
            assert abs(side[key] - expected) < 0.0011, (key, side[key], expected)
    assert c["reported_max_us"] + 1 == c["latency_us"]["max"], c
    for key in ("p50", "p90", "p99", "p99_9", "max"):
        ratio = t["wake_latency_us"][key] / c["latency_us"][key]
        assert abs(s["ratio_trainer_over_cyclictest"][key] - ratio) < 0.001, key
    png = os.path.join(directory, "jitter.png")
    if expect_plot:
        assert s["plot"] == "jitter.png", s["plot"]
        assert open(png, "rb").read(8) == b"\x89PNG\r\n\x1a\n", "jitter.png is not a PNG"
    else:
        assert s["plot"].startswith("not drawn: gnuplot") and "gnuplot-nox" in s["plot"], s["plot"]
        assert not os.path.exists(png)
    return s

seq = check(os.path.join(work, "seq"), "sequential", shutil.which("gnuplot") is not None)
assert seq["settings"]["cyclictest_cpu"] == cpu, seq["settings"]
assert seq["cyclictest"]["loops"] == seq["trainer"]["cycles"] == 1000, seq["cyclictest"]
assert "-l1000" in seq["cyclictest"]["command"].split(), seq["cyclictest"]["command"]
assert not seq["acceptance"]["evaluated"] and seq["acceptance"]["passed"]

along = check(os.path.join(work, "along"), "alongside", False)
assert along["trainer"]["cycles"] == 500, along["trainer"]
# cyclictest ran from before the trainer's start to after its end, stopped with SIGINT.
assert along["cyclictest"]["stopped_with_sigint"], along["cyclictest"]
assert along["cyclictest"]["loops"] >= 0.9 * along["trainer"]["cycles"], along["cyclictest"]
if cpus > 1:
    assert along["settings"]["cyclictest_cpu"] not in (-1, cpu), along["settings"]
acceptance = along["acceptance"]
assert acceptance["evaluated"] and not acceptance["passed"], acceptance
assert acceptance["max_ratio"] == 0.001 and len(acceptance["violations"]) == 2, acceptance
assert "p99.9" in acceptance["violations"][1], acceptance
print(f"jitter smoke: sequential trainer p99 {seq['trainer']['wake_latency_us']['p99']} us vs "
      f"cyclictest {seq['cyclictest']['latency_us']['p99']} us; alongside "
      f"{along['cyclictest']['loops']} cyclictest loops over {along['trainer']['cycles']} cycles")
PY
