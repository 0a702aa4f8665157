#!/usr/bin/env bash
# Runs inside the bench VM: waits until simdrive has booted every drive it simulates, before
# the master (trainer) starts. On a bench the drives are powered before the master; here the
# emulated simdrive can take seconds to start on a loaded host, while the trainer gives every
# node canopen.boot_timeout_ms (3 s of real time, not slowed) to send its boot-up after the NMT
# reset, so starting both at once failed now and then under load.
#   simdrive_booted.sh EVENTS_JSONL SIMDRIVE_LOG PID [TIMEOUT_S]
# EVENTS_JSONL: simdrive's --events file; SIMDRIVE_LOG: its stderr ("simdrive: N drives of ...").
# Exit 0 when N distinct nodes logged "boot", 1 when simdrive exited or TIMEOUT_S (60) passed.
set -uo pipefail
events=$1 log=$2 pid=$3 timeout_s=${4:-60}
deadline=$((SECONDS + timeout_s))
while [ "$SECONDS" -lt "$deadline" ]; do
  kill -0 "$pid" 2>/dev/null || { echo "simdrive_booted: simdrive (pid $pid) exited" >&2; exit 1; }
  drives=$(sed -n 's/^simdrive: \([0-9][0-9]*\) drives of .*/\1/p' "$log" 2>/dev/null | head -n 1)
  if [ -n "$drives" ]; then
    booted=$(grep -o '"node":[0-9]*,"event":"boot"' "$events" 2>/dev/null | sort -u | wc -l)
    [ "$booted" -lt "$drives" ] || exit 0
  fi
  sleep 0.05
done
echo "simdrive_booted: simdrive did not boot its drives within $timeout_s s" >&2
exit 1
