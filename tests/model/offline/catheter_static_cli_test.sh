#!/usr/bin/env bash
# `modelc catheter-static` against small-deflection beam theory through the real binary:
# tip deflection F L^3 / (3 EI) within 1 % at N = 41 (the chain's discretisation error there is
# 2.5e-4, see docs/catheter.md), and a malformed force refused with a message.
# usage: catheter_static_cli_test.sh MODELC
set -euo pipefail
modelc=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$modelc" catheter-static --length 0.3 --ei 3.9e-5 --ea 157 --particles 41 \
  --tip-force 0,1e-5,0 --report "$work/r.json" >/dev/null
python3 - "$work/r.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
beam = 1e-5 * 0.3 ** 3 / (3 * 3.9e-5)
tip = r["tip_displacement_m"][1]
assert abs(tip - beam) < 0.01 * beam, (tip, beam)
assert r["residual_n"] < 1e-9, r["residual_n"]
print(f"tip deflection {tip:.6e} m, beam theory {beam:.6e} m, ratio {tip / beam:.5f}")
PY
if "$modelc" catheter-static --length 0.3 --ei 3.9e-5 --ea 157 --particles 41 \
     --tip-force 0,x,0 --report "$work/bad.json" >"$work/bad.txt" 2>&1; then
  echo "a malformed force was accepted"; exit 1
fi
grep -q "tip-force" "$work/bad.txt" || { echo "message does not name the option"; cat "$work/bad.txt"; exit 1; }
