#!/usr/bin/env python3
"""Compares the trainer's report of a run over CAN (the bench VM: trainer + simdrive on vcan0)
with the report of the same scene on the simulated bench in simulated time.

The CAN run is real time under an emulator, and over the bus the encoders lag one SYNC and the
torque is applied one SYNC later than on the simulated bench, so the figures are compared with
stated tolerances, not bit for bit:
  - the CAN run completed every cycle, armed throughout but for the start-up cycles, no fault
    latched, no heap allocation after arming, every output zeroed at exit, backend canopen;
  - per instrument: mean contact force within 20 % (or 0.05 N), contact cycles within 10 %
    (or 50), catheter grasps equal; the peak force is shown, not compared: it is one cycle's
    transient at a contact onset, and the one-SYNC delay changes such transients;
  - per catheter model with an insertion goal: target reached alike, peak depth within 15 %;
  - the bus: SYNCs sent = cycles, no frame dropped by the kernel, none malformed.
Prints a table and exits 1 when a check fails.
usage: compare_reports.py SIM_REPORT CAN_REPORT
"""
import json
import sys


def main():
    sim = json.load(open(sys.argv[1]))
    can = json.load(open(sys.argv[2]))
    failures = []
    rows = []

    def check(name, sim_value, can_value, ok):
        rows.append((name, sim_value, can_value, "ok" if ok else "FAIL"))
        if not ok:
            failures.append(name)

    def close(a, b, rel, absolute):
        return abs(a - b) <= max(rel * max(abs(a), abs(b)), absolute)

    check("backend", sim["hal"], can["hal"], can["hal"] == "canopen")
    check("cycles", sim["cycles"], can["cycles"], can["cycles"] == can["requested_cycles"])
    check("faults at end", sim["safety"]["faults_latched_at_end"],
          can["safety"]["faults_latched_at_end"], can["safety"]["faults_latched_at_end"] == 0)
    check("first fault", sim["safety"]["first_fault"], can["safety"]["first_fault"],
          can["safety"]["first_fault"] == "none")
    check("armed cycles", sim["armed_cycles"], can["armed_cycles"],
          can["armed_cycles"] >= can["cycles"] - 10)
    check("heap after arming", sim["memory"]["heap_allocations_after_arming"],
          can["memory"]["heap_allocations_after_arming"],
          can["memory"]["heap_allocations_after_arming"] == 0)
    check("outputs zeroed at exit", sim["safety"]["outputs_zeroed_at_exit"],
          can["safety"]["outputs_zeroed_at_exit"], can["safety"]["outputs_zeroed_at_exit"])
    for s, c in zip(sim["instruments"], can["instruments"]):
        name = s["name"]
        check(f"{name} mean contact force N", round(s["mean_contact_force_n"], 3),
              round(c["mean_contact_force_n"], 3),
              close(s["mean_contact_force_n"], c["mean_contact_force_n"], 0.20, 0.05))
        rows.append((f"{name} peak force N (shown)", round(s["peak_force_n"], 3),
                     round(c["peak_force_n"], 3), "-"))
        check(f"{name} contact cycles", s["contact_cycles"], c["contact_cycles"],
              close(s["contact_cycles"], c["contact_cycles"], 0.10, 50))
        check(f"{name} catheter grasps", s["catheter"]["grasps"], c["catheter"]["grasps"],
              s["catheter"]["grasps"] == c["catheter"]["grasps"])
    for s, c in zip(sim["models"], can["models"]):
        if s.get("insertion") is None:
            continue
        si, ci = s["insertion"], c["insertion"]
        check(f"{s['name']} target reached", si["target_reached"], ci["target_reached"],
              si["target_reached"] == ci["target_reached"])
        check(f"{s['name']} peak depth m", round(si["peak_depth_m"], 4), round(ci["peak_depth_m"], 4),
              close(si["peak_depth_m"], ci["peak_depth_m"], 0.15, 0.001))
    bus = can.get("can") or {}
    transport = bus.get("transport", {})
    check("SYNCs sent", "-", bus.get("sync_sent"), bus.get("sync_sent", 0) >= can["cycles"])
    check("kernel drops", "-", transport.get("rx_kernel_drops"), transport.get("rx_kernel_drops") == 0)
    check("frames rejected", "-", bus.get("frames_rejected"), bus.get("frames_rejected") == 0)
    check("CAN faults", "-", bus.get("faults"), bus.get("faults") == "")

    width = max(len(r[0]) for r in rows)
    print(f"{'figure':<{width}}  {'sim':>14}  {'can':>14}")
    for name, s, c, verdict in rows:
        print(f"{name:<{width}}  {str(s):>14}  {str(c):>14}  {verdict}")
    split = can.get("step_split_ns", {})
    for phase in ("hal_read", "hal_write"):
        if phase in split:
            print(f"CAN {phase} p50/p99 ns: {split[phase].get('p50')}/{split[phase].get('p99')}")
    if failures:
        print("FAILED: " + ", ".join(failures))
        return 1
    print("all figures comparable")
    return 0


if __name__ == "__main__":
    sys.exit(main())
