#!/usr/bin/env python3
"""Judges can_faults.sh's sessions: for each injected fault the trainer must have latched a
fault, in the cycle after the drives acted on it (the SYNC the fault was scheduled at is sent at
the end of cycle SYNC-2: the first SYNC is activate()'s), at most one cycle later for a missing
PDO (one late answer is tolerated), and have been disarmed (zero force) from that cycle on; and
at the end every drive, as simdrive reports it, must be without torque and not in Operation
enabled. The trainer's own shutdown check (outputs_zeroed_at_exit, asked over SDO) cannot get
an answer from a silent or bus-off drive: it then says no, which is right, and the drives'
view decides.
Prints a table (the docs keep it) and exits 1 on a failure.
usage: check_faults.py OUT_DIR"""
import glob
import json
import os
import re
import sys

AT_SYNC = 200
ACTED_CYCLE = AT_SYNC - 1  # the first cycle that can see the drives' reaction


def drives_off(simdrive_text):
    """(all drives without torque and not enabled, number of drives) from simdrive's summary."""
    nodes = re.findall(r"^\s*node\s+\d+ \S+\s+NMT .*? power (.*?)\s+torque\s+(-?\d+) permille",
                       simdrive_text, re.M)
    off = all(int(torque) == 0 and power.strip() != "operation enabled" for power, torque in nodes)
    return off and len(nodes) > 0, len(nodes)


def main():
    out = sys.argv[1]
    failures = 0
    print(f"{'fault (at SYNC 200)':<44} {'first fault':<16} {'cycle':>5} {'after':>5} "
          f"{'armed':>5} {'off':>4} {'asked':>5}  CAN faults")
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
        off, drives = drives_off(open(spec_file[:-len(".spec")] + ".simdrive.txt").read())
        ok = (safety["first_fault"] != "none" and 0 <= after <= 2 and
              r["armed_cycles"] <= cycle + 1 and r["memory"]["heap_allocations_after_arming"] == 0
              and off and drives == 10)
        can_faults = (r.get("can") or {}).get("faults", "")
        print(f"{spec:<44} {safety['first_fault']:<16} {cycle:>5} {after:>+5} "
              f"{r['armed_cycles']:>5} {'yes' if off else 'NO':>4} "
              f"{'yes' if safety['outputs_zeroed_at_exit'] else 'no':>5}  {can_faults}  "
              f"{'ok' if ok else 'FAIL'}")
        failures += 0 if ok else 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
