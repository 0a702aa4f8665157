#!/usr/bin/env bash
# candecode over a hand-written candump -l log: every CANopen function decoded with its
# meaning (tests/tools/candecode/sample.log), and a malformed log refused with status 1.
#   candecode_test.sh CANDECODE SOURCE_DIR
set -euo pipefail
candecode=$1
src=$2
here=$src/tests/tools/candecode
out=$("$candecode" --device "$src/config/devices/canopen_vcan.toml" "$here/sample.log")
expect() {
  grep -qF -- "$1" <<<"$out" || { echo "FAIL: missing '$1' in:"; echo "$out"; exit 1; }
}
expect "NMT reset communication"
expect "BOOT-UP node 1 (left.pitch)"
expect "SDO -> node 1 (left.pitch) read 0x1018:01"
expect "SDO <- node 1 (left.pitch) read 0x1018:01 = 0x000000FB"
expect "TPDO1 node 1 (left.pitch) statusword 0x0027, position 1000 counts, torque 20 permille"
expect "RPDO1 node 1 (left.pitch) controlword 0x000F, target torque 1000 permille"
expect "EMCY node 1 (left.pitch) 0x2310 (continuous over-current"
expect "ERROR FRAME bus-off"
expect "abort 0x6040:00 0x06020000 (object does not exist"
expect "candecode: 11 frames"
expect "; 0 undecodable"
status=0
"$candecode" "$here/malformed.log" >/tmp/candecode_malformed.$$ || status=$?
if [ "$status" -ne 1 ] || ! grep -q "2 frames, .*; 2 undecodable" /tmp/candecode_malformed.$$; then
  echo "FAIL: a malformed log gave status $status:"; cat /tmp/candecode_malformed.$$; exit 1
fi
rm -f /tmp/candecode_malformed.$$
echo "PASS"
