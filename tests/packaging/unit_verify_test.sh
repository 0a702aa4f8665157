#!/usr/bin/env bash
# `systemd-analyze verify` on packaging/systemd/trainer.service, with ExecStart pointing at the
# trainer just built (verify refuses a unit whose binary does not exist). Any message on stderr
# (an unknown key, a bad value) fails the test as well as a non-zero exit.
# usage: unit_verify_test.sh UNIT_FILE TRAINER_BINARY
set -euo pipefail
unit=$1
trainer=$2
command -v systemd-analyze >/dev/null || { echo "systemd-analyze not installed"; exit 77; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sed "s|/usr/bin/trainer|$trainer|" "$unit" >"$work/trainer.service"
status=0
systemd-analyze verify --man=no "$work/trainer.service" 2>"$work/stderr.txt" || status=$?
cat "$work/stderr.txt"
[ "$status" -eq 0 ] || { echo "systemd-analyze verify: exit $status"; exit 1; }
[ ! -s "$work/stderr.txt" ] || { echo "systemd-analyze verify printed the messages above"; exit 1; }
# What the appliance relies on, checked in the file itself.
for key in Type=notify WatchdogSec= Restart=on-failure LimitRTPRIO= LimitMEMLOCK=infinity \
           User=trainer StateDirectory=trainer AF_CAN; do
  grep -q "$key" "$unit" || { echo "trainer.service lacks $key"; exit 1; }
done
if grep -Eq '^(RestrictRealtime=yes|PrivateDevices=yes|DevicePolicy=)' "$unit"; then
  echo "trainer.service has an option that breaks SCHED_FIFO or device access"; exit 1
fi
echo "trainer.service verifies ($(systemd-analyze --version | head -n1))"
