#!/usr/bin/env python3
"""hil against simdrive over vcan0, inside the bench VM (docs/hil.md "Bench VM tests").

usage: hil_can_bench.py BIN_DIR OUT_DIR MODE [TRIALS]   (MODE all = good, then miswired)
  MODE good      a bench wired as config/devices/canopen_vcan.toml says: `hil scan` and
                 `hil check --only can/left.yaw --only can/bus` (heartbeat loss TRIALS times)
                 must pass (exit 0) with every step pass.
  MODE miswired  simdrive --miswire reverse_encoder:node=2 --node-id-map 3=13: `hil scan` must
                 fail left.insertion (missing) and node 13 (extra) and write the node_id
                 correction (--write-device); `hil check` of left.yaw with that file must fail
                 encoder_direction and write encoder_direction = -1; with the twice corrected
                 file scan and check must pass.
  MODE trials    `hil check --only can/left.pitch.heartbeat_loss --trials TRIALS`: the
                 distribution for docs/hil.md (report in OUT_DIR/trials.json).
simdrive gets the same --slow-motion as hil; its stdin is a FIFO the --act script writes to
(tests/benchvm/hil_act.sh). Exit 0 when every expectation held, 1 otherwise.
"""
import json
import os
import subprocess
import sys
import tempfile
import time

DEVICE = "config/devices/canopen_vcan.toml"
SCENE = "config/scenes/wall.toml"
SLOW = "8"


def start_simdrive(bin_dir, out_dir, extra, slow=SLOW):
    # The guest's own /tmp: the out directory is a 9p share, which has no FIFOs.
    fifo = os.path.join(tempfile.mkdtemp(prefix="hil_"), "simdrive_stdin")
    os.mkfifo(fifo)
    stdin = os.open(fifo, os.O_RDWR)  # a writer always open: no EOF between actions
    events = os.path.join(out_dir, "simdrive_events.jsonl")
    open(events, "w").close()
    log = open(os.path.join(out_dir, "simdrive.txt"), "a")
    proc = subprocess.Popen(
        ["chrt", "-f", "50", os.path.join(bin_dir, "simdrive"), "--scene", SCENE, "--device",
         DEVICE, "--slow-motion", slow, "--events", events] + extra,
        stdin=stdin, stdout=log, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        with open(events) as f:
            boots = {json.loads(l)["node"] for l in f if '"boot"' in l}
        if len(boots) >= 10:
            return proc, fifo
        time.sleep(0.05)
    proc.kill()
    raise SystemExit("simdrive did not come up")


def hil(bin_dir, out_dir, name, args, device=DEVICE, fifo=None, slow=SLOW, rt=False):
    report = os.path.join(out_dir, name + ".json")
    # rt: the master on a real-time priority below simdrive's, as a bench's master would run.
    command = (["chrt", "-f", "40"] if rt else []) + [os.path.join(bin_dir, "hil"), "--device", device, "--slow-motion", slow, "--yes",
               "--report-json", report, "--report-md", os.path.join(out_dir, name + ".md")]
    if fifo:
        command += ["--act", "tests/benchvm/hil_act.sh " + fifo]
    start = time.monotonic()
    result = subprocess.run(command + args, capture_output=True, text=True)
    seconds = time.monotonic() - start
    with open(os.path.join(out_dir, name + ".txt"), "w") as f:
        f.write(result.stdout + result.stderr)
    print(f"--- hil {' '.join(args)}: exit {result.returncode} in {seconds:.1f} s")
    print(result.stdout + result.stderr)
    with open(report) as f:
        return result.returncode, json.load(f)


def steps_of(report):
    steps = {}
    for scan in report["scans"]:
        for step in scan["comparison"]:
            steps[step["id"]] = step
    for check in report["checks"]:
        for step in check["steps"]:
            steps[step["id"]] = step
    return steps


class Expect:
    def __init__(self):
        self.failures = []

    def __call__(self, condition, what):
        print(("ok   " if condition else "FAIL ") + what)
        if not condition:
            self.failures.append(what)


def good(bin_dir, out_dir, trials, expect):
    simdrive, fifo = start_simdrive(bin_dir, out_dir, [])
    try:
        status, scan = hil(bin_dir, out_dir, "scan", ["scan"])
        expect(status == 0, "scan of the good bench exits 0")
        expect(len(scan["scans"][0]["found"]) == 10, "scan finds 10 nodes")
        expect(all(s["outcome"] == "pass" for s in steps_of(scan).values()), "every scan step passes")
        status, check = hil(bin_dir, out_dir, "check",
                            ["check", "--only", "can/left.yaw", "--trials", str(trials)], fifo=fifo)
        steps = steps_of(check)
        expect(status == 0, "check of the good bench exits 0")
        for step in ("torque_limit", "encoder_direction", "motor_polarity", "heartbeat_loss"):
            expect(steps.get("can.left.yaw." + step, {}).get("outcome") == "pass", "left.yaw " + step + " passes")
        expect(check["corrections"] == [], "no corrections")
    except BaseException:
        simdrive.kill()
        raise
    # The bus statistics with all ten drives answering every SYNC. Measured and reported; their
    # pass criterion (SYNC interval within 25 % of the period, TPDO1 within the period) is a
    # bench's, which TCG on a shared host misses now and then (docs/hil.md): checked here are
    # the figures, not the verdict.
    status, check = hil(bin_dir, out_dir, "check_bus",
                        ["check", "--only", "can/bus", "--jitter-syncs", "200"], rt=True)
    steps = steps_of(check)
    expect(status in (0, 1), "bus statistics ran (exit 0 or 1)")
    jitter = {f["name"]: f["value"] for f in steps.get("can.bus.sync_jitter", {}).get("figures", [])}
    trip = {f["name"]: f["value"] for f in steps.get("can.bus.pdo_round_trip", {}).get("figures", [])}
    expect(jitter.get("syncs") == 200, "200 SYNCs measured")
    expect(trip.get("drives") == 10 and trip.get("samples", 0) >= 0.9 * 200 * 10,
           "at least 90 % of the TPDO1 answers timed")
    expect(0 < trip.get("p50", 0) < 4.0, "median round trip within the period")
    simdrive.terminate()
    simdrive.wait()


def miswired(bin_dir, out_dir, expect):
    simdrive, fifo = start_simdrive(bin_dir, out_dir,
                                    ["--miswire", "reverse_encoder:node=2", "--node-id-map", "3=13"])
    fixed1 = os.path.join(out_dir, "fixed_node_id.toml")
    fixed2 = os.path.join(out_dir, "fixed.toml")
    try:
        status, scan = hil(bin_dir, out_dir, "scan_miswired", ["--write-device", fixed1, "scan"])
        steps = steps_of(scan)
        expect(status == 1, "scan of the miswired bench exits 1")
        expect(steps.get("can.scan.left.insertion", {}).get("outcome") == "fail", "left.insertion missing")
        expect(steps.get("can.scan.extra.node13", {}).get("outcome") == "fail", "node 13 extra")
        expect([(c["key"], c["old_value"], c["new_value"]) for c in scan["corrections"]]
               == [("node_id", "3", "13")], "the node_id correction 3 -> 13")
        expect(os.path.exists(fixed1) and scan["corrected_device_file"] is not None, "written to " + fixed1)
        only = ["--only", "can/left.yaw.encoder_direction", "--only", "can/left.yaw.motor_polarity"]
        status, check = hil(bin_dir, out_dir, "check_miswired", ["--write-device", fixed2, "check"] + only,
                            device=fixed1, fifo=fifo)
        steps = steps_of(check)
        expect(status == 1, "check of the reversed encoder exits 1")
        expect(steps.get("can.left.yaw.encoder_direction", {}).get("outcome") == "fail", "encoder_direction fails")
        expect(steps.get("can.left.yaw.motor_polarity", {}).get("outcome") == "pass",
               "motor_polarity passes (read through the measured encoder)")
        expect([(c["table"], c["instrument"], c["key"], c["new_value"]) for c in check["corrections"]]
               == [("instrument.yaw", "left", "encoder_direction", "-1")], "the encoder_direction correction")
        expect(os.path.exists(fixed2), "written to " + fixed2)
        status, scan = hil(bin_dir, out_dir, "scan_fixed", ["scan"], device=fixed2)
        expect(status == 0, "scan with the corrected file exits 0")
        status, check = hil(bin_dir, out_dir, "check_fixed",
                            ["check", "--only", "can/left.yaw.encoder_direction",
                             "--only", "can/left.insertion.torque_limit"],
                            device=fixed2, fifo=fifo)
        expect(status == 0, "check with the corrected file exits 0")
    finally:
        simdrive.terminate()
        simdrive.wait()


def trials_mode(bin_dir, out_dir, trials, expect):
    simdrive, fifo = start_simdrive(bin_dir, out_dir, [])
    try:
        status, check = hil(bin_dir, out_dir, "trials",
                            ["check", "--only", "can/left.pitch.heartbeat_loss", "--trials", str(trials)])
        step = steps_of(check).get("can.left.pitch.heartbeat_loss", {})
        expect(status == 0 and step.get("outcome") == "pass", "heartbeat loss over the trials passes")
        print(json.dumps({f["name"]: f["value"] for f in step.get("figures", [])}))
    finally:
        simdrive.terminate()
        simdrive.wait()


def main():
    bin_dir, out_dir, mode = sys.argv[1:4]
    trials = int(sys.argv[4]) if len(sys.argv) > 4 else 3
    os.makedirs(out_dir, exist_ok=True)
    expect = Expect()
    start = time.monotonic()
    if mode in ("good", "all"):
        good(bin_dir, out_dir, trials, expect)
    if mode in ("miswired", "all"):
        miswired(bin_dir, out_dir, expect)
    if mode == "trials":
        trials_mode(bin_dir, out_dir, trials, expect)
    print(f"{mode}: {len(expect.failures)} failed expectations, {time.monotonic() - start:.1f} s in the guest")
    return 1 if expect.failures else 0


if __name__ == "__main__":
    sys.exit(main())
