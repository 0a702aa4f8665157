#!/usr/bin/env python3
"""Judges can_faults.sh's sessions: for each injected fault the trainer must have latched a
fault, in the cycle after the drives acted on it (the SYNC the fault was scheduled at is sent at
the end of cycle SYNC-2: the first SYNC is activate()'s), at most one cycle later for a missing
PDO (one late answer is tolerated), and have been disarmed (zero force) from that cycle on.
Prints a table (the docs keep it) and exits 1 on a failure.
usage: check_faults.py OUT_DIR"""
import glob
import json
import os
import sys

AT_SYNC = 300
ACTED_CYCLE = AT_SYNC - 1  # the first cycle that can see the drives' reaction


def main():
    out = sys.argv[1]
    failures = 0
    print(f"{'fault (at SYNC 300)':<44} {'first fault':<16} {'cycle':>5} {'after':>5} "
          f"{'armed':>5}  CAN faults")
    for spec_file in sorted(glob.glob(os.path.join(out, "fault_*.spec")),
                            key=lambda p: int(p.split("_")[-1].split(".")[0])):
        spec = open(spec_file).read().strip()
        report_file = spec_file[:-len(".spec")] + ".json"
        if not os.path.exists(report_file):
            print(f"{spec:<44} no report (trainer failed to start)")
            failures += 1
            continue
        r = json.load(open(report_file))
        safety = r["safety"]
        cycle = safety["first_fault_cycle"]
        after = cycle - ACTED_CYCLE
        ok = (safety["first_fault"] != "none" and 0 <= after <= 2 and
              r["armed_cycles"] <= cycle + 1 and r["memory"]["heap_allocations_after_arming"] == 0
              and safety["outputs_zeroed_at_exit"])
        can_faults = (r.get("can") or {}).get("faults", "")
        print(f"{spec:<44} {safety['first_fault']:<16} {cycle:>5} {after:>+5} "
              f"{r['armed_cycles']:>5}  {can_faults}  {'ok' if ok else 'FAIL'}")
        failures += 0 if ok else 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
