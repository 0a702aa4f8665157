#!/usr/bin/env python3
"""A killed trainer must not leave torque on: runs inside the bench VM (vcan0), simdrive as
the drives, and for each trial starts the trainer, waits until every drive reports torque
enabled, kills the trainer with SIGKILL at a random moment, and measures how long each drive
takes to remove torque by itself (heartbeat consumer 0x1016 or RPDO deadline, then the abort
connection option 0x6007). Times are CLOCK_MONOTONIC, shared by this script and simdrive's
events log.

usage: can_kill_trials.py BIN_DIR SCENE DEVICE TRIALS OUT_JSON [SLOW_MOTION]
Writes OUT_JSON: per trial the worst drive's latency and the causes, and the distribution.
Exit status 0 when every trial ended with every drive's torque off within the drives'
heartbeat consumer time (drive_heartbeat_consumer_ms of the device file), 1 otherwise.
"""
import json
import os
import random
import signal
import subprocess
import sys
import time
import tomllib


def read_events(path, offset):
    """New complete lines of the events log from byte `offset`; returns (events, offset)."""
    events = []
    with open(path, "rb") as f:
        f.seek(offset)
        data = f.read()
    end = data.rfind(b"\n") + 1
    for line in data[:end].splitlines():
        if line.strip():
            events.append(json.loads(line))
    return events, offset + end


def wait_for(path, offset, done, timeout_s):
    """Reads events until done(events_so_far) or the timeout; returns (events, offset, ok)."""
    seen = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        new, offset = read_events(path, offset)
        seen.extend(new)
        if done(seen):
            return seen, offset, True
        time.sleep(0.005)
    return seen, offset, False


def percentile(values, q):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


def main():
    bin_dir, scene, device, trials, out_json = sys.argv[1:6]
    slow_motion = int(sys.argv[6]) if len(sys.argv) > 6 else 1
    trials = int(trials)
    with open(device, "rb") as f:
        device_file = tomllib.load(f)
    canopen = device_file["canopen"]
    consumer_ms = canopen.get("drive_heartbeat_consumer_ms", 30)
    rpdo_ms = canopen.get("rpdo_timeout_ms", 10)
    nodes = sorted(j["node_id"] for inst in device_file["instrument"]
                   for j in (inst[k] for k in ("pitch", "yaw", "insertion", "roll", "grip")))
    out_dir = os.path.dirname(os.path.abspath(out_json))
    events_path = os.path.join(out_dir, "kill_trials_events.jsonl")
    open(events_path, "w").close()
    sim_log = open(os.path.join(out_dir, "kill_trials_simdrive.txt"), "w")
    # The drives are separate hardware on a real bench: a real-time priority here, so that the
    # emulated trainer never starves them.
    simdrive = subprocess.Popen(
        ["chrt", "-f", "50", os.path.join(bin_dir, "simdrive"), "--scene", scene, "--device", device,
         "--no-stdin", "--events", events_path] + (["--slow-motion", str(slow_motion)] if slow_motion > 1 else []),
        stdout=sim_log, stderr=subprocess.STDOUT)
    # simdrive is up when every node has announced its boot-up.
    booted = set()

    def all_booted(events):
        booted.update(e["node"] for e in events if e["event"] == "boot")
        return booted >= set(nodes)

    _, offset, ok = wait_for(events_path, 0, all_booted, 30.0)
    if not ok:
        print(f"simdrive did not come up: boot-ups from {sorted(booted)} of {nodes}")
        simdrive.kill()
        return 1
    rng = random.Random(15)
    results = []
    failures = 0
    lost_precondition = 0
    startup_faults = 0
    startup_reasons = []
    trial = 0
    try:
        while trial < trials:
            trainer_log_path = os.path.join(out_dir, "kill_trials_trainer.txt")
            trainer_log = open(trainer_log_path, "w")
            trainer = subprocess.Popen(
                [os.path.join(bin_dir, "trainer"), "--scene", scene, "--device", device, "--no-rt"]
                + (["--slow-motion", str(slow_motion)] if slow_motion > 1 else []),
                stdout=trainer_log, stderr=subprocess.STDOUT)
            enabled = set()

            def all_enabled(events):
                for e in events:
                    if e["event"] == "torque_enabled":
                        enabled.add(e["node"])
                    elif e["event"] == "torque_removed":
                        enabled.discard(e["node"])
                return enabled >= set(nodes)

            _, offset, ok = wait_for(events_path, offset, all_enabled, 30.0)
            if not ok:
                # A trainer that latched a fault while starting never enables the drives (under
                # the emulator: a start-up hiccup longer than two SYNC periods gives
                # pdo_timeout). Not what a kill trial measures: stopped with SIGINT so that it
                # reports why, counted, and run again.
                trainer.send_signal(signal.SIGINT)
                try:
                    trainer.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    trainer.kill()
                    trainer.wait()
                trainer_log.close()
                startup_faults += 1
                output = open(trainer_log_path).read()
                reason = [l.strip() for l in output.splitlines()
                          if "first fault" in l or "CAN faults" in l or "can:" in l]
                print(f"trial {trial}: the trainer never enabled every drive ({sorted(enabled)} "
                      f"of {nodes}); run again. Its report: {reason}")
                startup_reasons.append(output[-2000:])
                if startup_faults > trials:
                    failures += 1
                    break
                time.sleep(0.5)
                continue
            time.sleep(rng.uniform(0.05, 0.3))
            t_kill = time.monotonic_ns()
            trainer.send_signal(signal.SIGKILL)
            trainer.wait()
            # Every drive must still have had torque on at the kill: a trainer that latched a
            # fault during the wait (a slow emulator missing a deadline) had already switched
            # them off, and the trial measures nothing. It is counted and run again.
            before_kill, offset = read_events(events_path, offset)
            still_on = set(enabled)
            for e in before_kill:
                if e["t_ns"] < t_kill and e["event"] == "torque_removed":
                    still_on.discard(e["node"])
            if still_on != set(nodes):
                lost_precondition += 1
                print(f"trial {trial}: drives {sorted(set(nodes) - still_on)} were already off "
                      f"before the kill (the trainer had stopped them); trial run again")
                if lost_precondition > trials:
                    failures += 1
                    break
                time.sleep(0.5)
                continue
            removed = {}

            def all_removed(events):
                for e in before_kill + events:
                    if e["event"] == "torque_removed" and e["t_ns"] >= t_kill:
                        removed.setdefault(e["node"], e)
                return set(removed) >= set(nodes)

            _, offset, ok = wait_for(events_path, offset, all_removed, 5.0)
            latencies = {n: (removed[n]["t_ns"] - t_kill) / 1e6 for n in removed}
            worst = max(latencies.values()) if latencies else None
            causes = sorted({removed[n].get("cause", "?") for n in removed})
            result = {"trial": trial, "worst_ms": worst, "causes": causes,
                      "nodes_removed": len(removed)}
            results.append(result)
            # simdrive's events are on the real CLOCK_MONOTONIC; its protocol timers run slowed.
            if not ok or worst is None or worst > consumer_ms * slow_motion:
                failures += 1
                print(f"trial {trial}: FAIL {result}")
            # Let the drives' state settle (they are in quick stop / switch on disabled) and
            # the next trainer's NMT reset start from a quiet bus.
            time.sleep(0.1)
            trial += 1
    finally:
        simdrive.send_signal(signal.SIGINT)
        try:
            simdrive.wait(timeout=10)
        except subprocess.TimeoutExpired:
            simdrive.kill()
    worst = [r["worst_ms"] for r in results if r.get("worst_ms") is not None]
    summary = {
        "trials": trials,
        "failed": failures,
        "rerun_precondition_lost": lost_precondition,
        "rerun_startup_fault": startup_faults,
        "startup_fault_reports": startup_reasons,
        "slow_motion": slow_motion,
        "drive_heartbeat_consumer_ms": consumer_ms,
        "rpdo_timeout_ms": rpdo_ms,
        "drives": len(nodes),
        # Wall-clock ms; divided by slow_motion they are the drives' (and the trainer's) ms.
        "worst_drive_latency_ms": {
            "min": min(worst), "p50": percentile(worst, 0.5), "p90": percentile(worst, 0.9),
            "p99": percentile(worst, 0.99), "max": max(worst)} if worst else None,
        "causes": sorted({c for r in results for c in r.get("causes", [])}),
        "results": results,
    }
    with open(out_json, "w") as f:
        json.dump(summary, f, indent=2)
    d = summary["worst_drive_latency_ms"]
    print(f"kill trials (slow motion x{slow_motion}, times on the drives' clock = wall / "
          f"{slow_motion}):")
    if d:
        d = {k: v / slow_motion for k, v in d.items()}
    print(f"kill trials: {trials - failures}/{trials} passed; time from SIGKILL to the last of "
          f"{len(nodes)} drives without torque, ms: " +
          (f"min {d['min']:.1f} p50 {d['p50']:.1f} p90 {d['p90']:.1f} p99 {d['p99']:.1f} "
           f"max {d['max']:.1f}" if d else "none") +
          f" (consumer time {consumer_ms} ms, RPDO deadline {rpdo_ms} ms); causes: {summary['causes']}; "
          f"run again: {lost_precondition} (drives already off before the kill), "
          f"{startup_faults} (the trainer latched a fault while starting)")
    return 0 if failures == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
