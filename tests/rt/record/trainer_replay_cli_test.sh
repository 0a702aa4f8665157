#!/bin/sh
# trainer --record/--replay as a user runs them (docs/recording.md): a session run with
# --report-dir is recorded next to its report and named like it; --replay of it exits 0 with
# the all-identical line; a truncated copy replays up to the damage (exit 4, the byte named);
# a file that is not a recording is refused (exit 1); --no-record records nothing; --replay
# --report FILE writes the result as JSON.
# Usage: trainer_replay_cli_test.sh TRAINER SOURCE_DIR
set -eu
trainer=$1
source_dir=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$trainer" --scene "$source_dir/config/scenes/wall.toml" --time simulated --cycles 3000 \
  --report-dir "$work/reports" >"$work/run.txt" 2>&1 || fail "run: $(cat "$work/run.txt")"
report=$(readlink -f "$work/reports/latest.json")
recording="${report%.json}.mcap"
[ -f "$recording" ] || fail "no recording $recording beside $report: $(ls "$work/reports")"
grep -q "\"file\": \"$recording\"" "$report" || fail "the report does not name $recording"
ls "$work/reports" | grep -q '^\.recording' && fail "temporary recording left behind"

"$trainer" --replay "$recording" --report "$work/replay.json" >"$work/replay.txt" 2>&1 ||
  fail "replay: $(cat "$work/replay.txt")"
grep -q '"identical": true' "$work/replay.json" || fail "replay report: $(cat "$work/replay.json")"
grep -q '"cycles_replayed": 3000' "$work/replay.json" || fail "replay report cycles"
grep -q "(scene wall): 3000 cycles, all outputs and state hashes identical$" "$work/replay.txt" ||
  fail "replay said: $(cat "$work/replay.txt")"

size=$(stat -c %s "$recording")
head -c $((size * 2 / 3)) "$recording" >"$work/cut.mcap"
status=0
"$trainer" --replay "$work/cut.mcap" >"$work/cut.txt" 2>&1 || status=$?
[ "$status" = 4 ] || fail "truncated replay exit $status: $(cat "$work/cut.txt")"
grep -q "identical up to the damage: .*cut.mcap: byte [0-9]*: .*truncated" "$work/cut.txt" ||
  fail "truncated replay said: $(cat "$work/cut.txt")"

status=0
"$trainer" --replay "$source_dir/config/scenes/wall.toml" >"$work/bad.txt" 2>&1 || status=$?
[ "$status" = 1 ] || fail "non-recording replay exit $status"
grep -q "wall.toml: not an MCAP file" "$work/bad.txt" || fail "said: $(cat "$work/bad.txt")"

"$trainer" --scene "$source_dir/config/scenes/wall.toml" --time simulated --cycles 100 \
  --report-dir "$work/none" --no-record >/dev/null 2>&1 || fail "--no-record run"
ls "$work/none" | grep -q 'mcap$' && fail "--no-record recorded"
echo "record/replay CLI: ok"
