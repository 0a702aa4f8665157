#!/usr/bin/env python3
"""Compares the trainer's report of a run over a real kernel bus in the bench VM (CAN: trainer +
simdrive on vcan0; USB: trainer + usbgadget on dummy_hcd) with the report of the same scene on
the simulated bench in simulated time.

The bus run is real time under an emulator, and over the bus the encoders lag one exchange and
the torque is applied one exchange later than on the simulated bench, so the figures are
compared with stated tolerances, not bit for bit:
  - the bus run completed every cycle, armed throughout but for the start-up cycles, no fault
    latched, no heap allocation after arming, every output zeroed at exit, the backend the
    report's bus block belongs to (canopen or usb);
  - per instrument: mean contact force within 20 % (or 0.05 N), contact cycles within 10 %
    (or 50), catheter grasps equal; the peak force is shown, not compared: it is one cycle's
    transient at a contact onset, and the one-SYNC delay changes such transients;
  - per catheter model with an insertion goal: target reached alike, peak depth within 15 %;
  - CAN: SYNCs sent = cycles, no frame dropped by the kernel, none malformed, no CAN fault;
  - USB: an OUT report published per cycle, no IN report refused by the decoder, no USB fault,
    no transfer error, the device acknowledged zero + disable at the end; stale cycles and
    missed frames are shown (the stale limit latches a fault if they come in a row).
Prints a table and exits 1 when a check fails.
usage: compare_reports.py SIM_REPORT BUS_REPORT
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

    backend = "usb" if can.get("usb") else "canopen"
    check("backend", sim["hal"], can["hal"], can["hal"] == backend)
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
    if backend == "canopen":
        bus = can.get("can") or {}
        transport = bus.get("transport", {})
        check("SYNCs sent", "-", bus.get("sync_sent"), bus.get("sync_sent", 0) >= can["cycles"])
        check("kernel drops", "-", transport.get("rx_kernel_drops"),
              transport.get("rx_kernel_drops") == 0)
        check("frames rejected", "-", bus.get("frames_rejected"), bus.get("frames_rejected") == 0)
        check("CAN faults", "-", bus.get("faults"), bus.get("faults") == "")
    else:
        usb = can["usb"]
        check("OUT reports published", "-", usb["out_published"],
              usb["out_published"] >= can["cycles"])
        check("bad IN reports", "-", usb["bad_reports"], usb["bad_reports"] == 0)
        check("transfer errors", "-", usb["transfer_errors"], usb["transfer_errors"] == 0)
        check("USB faults", "-", usb["faults"], usb["faults"] == "")
        check("shutdown acknowledged", "-", usb["shutdown_acknowledged"],
              usb["shutdown_acknowledged"])
        for key in ("stale_frames", "stale_run_max", "missed_frames", "in_superseded", "acks"):
            rows.append((f"USB {key} (shown)", "-", usb[key], "-"))
        trip = usb["round_trip_us"]
        rows.append(("USB round trip p50/p99/max us (shown)", "-",
                     f"{trip['p50']:.0f}/{trip['p99']:.0f}/{trip['max']:.0f}", "-"))

    width = max(len(r[0]) for r in rows)
    print(f"{'figure':<{width}}  {'sim':>14}  {backend:>14}")
    for name, s, c, verdict in rows:
        print(f"{name:<{width}}  {str(s):>14}  {str(c):>14}  {verdict}")
    split = can.get("step_split_ns", {})
    for phase in ("hal_read", "hal_write"):
        if phase in split:
            print(f"{backend} {phase} p50/p99 ns: {split[phase].get('p50')}/{split[phase].get('p99')}")
    if failures:
        print("FAILED: " + ", ".join(failures))
        return 1
    print("all figures comparable")
    return 0


if __name__ == "__main__":
    sys.exit(main())
