#!/usr/bin/env python3
"""Runs inside the bench VM (benchvm run --gpio-sim): the whole trainer with its digital I/O on a
gpio-sim chip (config/devices/gpio_sim_bench.toml: the simulated bench's motion, real kernel GPIO
lines). The enable switch is held through its pull, the trainer arms (drive-enable line high),
then the e-stop is pressed for half a loop period only and released; the drive-enable line must
fall and stay low (a released e-stop never re-arms), the fault lamp light. Prints key=value
lines; gpio_trainer_test.sh judges them together with the trainer's report.
usage: gpio_trainer.py NAME BIN_DIR SLOW_MOTION CYCLES [DEVICE_FILE [simdrive|- [estop|enable]]]
NAME prefixes the files it writes to $BENCHVM_OUT (NAME.trainer.json, NAME.trainer.txt, ...).
With "enable" the event is a release of the enable (dead-man) switch for half a period instead
of an e-stop press, in a copy of the wall scene with safety.require_enable_input = true: the
trainer must latch enable_released and stay disarmed when the switch is held again.
DEVICE_FILE defaults to config/devices/gpio_sim_bench.toml; with "simdrive" the motion is a
canopen device file's drives, run as simdrive on vcan0 (e.g. canopen_vcan_gpio.toml)."""
import os
import subprocess
import sys
import time

CHIP_SH = "tests/benchvm/gpio_sim_chip.sh"
PERIOD_S = 0.001  # config/scenes/wall.toml loop.period_us
ESTOP, ENABLE, DRIVE_ENABLE, FAULT_LAMP = 0, 1, 2, 3


def chip_sh(*args):
    return subprocess.run([CHIP_SH, *args], check=True, capture_output=True, text=True).stdout.strip()


def main():
    name, bin_dir, slow, cycles = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    device = sys.argv[5] if len(sys.argv) > 5 else "config/devices/gpio_sim_bench.toml"
    with_simdrive = len(sys.argv) > 6 and sys.argv[6] == "simdrive"
    event = sys.argv[7] if len(sys.argv) > 7 else "estop"
    scene = "config/scenes/wall.toml"
    if event == "enable":
        # The wall scene with the enable switch required, its relative paths made absolute.
        text = open(scene).read()
        root = os.getcwd()
        text = text.replace('"../devices/sim.toml"', f'"{root}/config/devices/sim.toml"')
        text = text.replace('"../trajectories/', f'"{root}/config/trajectories/')
        text = text.replace("require_enable_input = false", "require_enable_input = true")
        assert "require_enable_input = true" in text
        scene = os.path.join(os.environ["BENCHVM_OUT"], f"{name}.scene.toml")
        open(scene, "w").write(text)
    out = os.path.join(os.environ["BENCHVM_OUT"], name)
    period = PERIOD_S * slow  # real seconds per cycle
    chip = chip_sh("create", "trainer", "trainer-bench", "estop", "enable", "drive_enable",
                   "fault_lamp")
    dev = open("/sys/kernel/config/gpio-sim/trainer/dev_name").read().strip()
    base = f"/sys/devices/platform/{dev}/{chip}"
    value_files = {n: open(f"{base}/sim_gpio{n}/value", "rb", buffering=0)
                   for n in (DRIVE_ENABLE, FAULT_LAMP)}

    def value(n):
        value_files[n].seek(0)
        return int(value_files[n].read().strip())

    estop_pull = os.open(f"{base}/sim_gpio{ESTOP}/pull", os.O_WRONLY)
    enable_pull = os.open(f"{base}/sim_gpio{ENABLE}/pull", os.O_WRONLY)
    print(f"session {name}: {device}{' with simdrive' if with_simdrive else ''}, slow motion x{slow}, "
          f"event {event}")
    print(f"chip={chip} dev={dev}")
    chip_sh("press", "trainer", str(ENABLE))  # the enable switch held
    print(f"before_start drive_enable={value(DRIVE_ENABLE)} fault_lamp={value(FAULT_LAMP)}")
    simdrive = None
    if with_simdrive:
        simdrive = subprocess.Popen(
            ["chrt", "-f", "50", f"{bin_dir}/simdrive", "--scene", scene,
             "--device", device, "--slow-motion", str(slow), "--no-stdin",
             "--events", f"{out}.simdrive_events.jsonl"],
            stdout=open(f"{out}.simdrive.txt", "w"), stderr=subprocess.STDOUT)
        # The drives up before the master, as on a bench (simdrive_booted.sh says why).
        if subprocess.run(["tests/benchvm/simdrive_booted.sh", f"{out}.simdrive_events.jsonl",
                           f"{out}.simdrive.txt", str(simdrive.pid)]).returncode != 0:
            print("simdrive_booted=no")
            simdrive.send_signal(2)
            simdrive.wait()
            return 1
    trainer = subprocess.Popen(
        [f"{bin_dir}/trainer", "--scene", scene,
         "--device", device, "--cycles", str(cycles),
         "--slow-motion", str(slow), "--no-rt", "--overrun-streak-limit", "1000",
         "--report", f"{out}.trainer.json"],
        stdout=open(f"{out}.trainer.txt", "w"), stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 60
    while value(DRIVE_ENABLE) != 1:
        if trainer.poll() is not None or time.monotonic() > deadline:
            print("armed=no")
            trainer.wait()
            if simdrive is not None:
                simdrive.send_signal(2)
                simdrive.wait()
            return 1
        time.sleep(0.001)
    print("armed=yes")
    print(f"armed_lamp fault_lamp={value(FAULT_LAMP)}")
    time.sleep(0.3)
    # A press of the e-stop (or a release of the enable switch) of half a period.
    pull, first, second = estop_pull, b"pull-up", b"pull-down"
    if event == "enable":
        pull, first, second = enable_pull, b"pull-down", b"pull-up"
    t0 = time.monotonic()
    os.write(pull, first)
    t_up = time.monotonic()
    while time.monotonic() - t0 < period / 2:
        pass
    os.write(pull, second)
    t_down = time.monotonic()
    print(f"press_held_ms={(t_down - t_up) * 1e3:.3f} period_ms={period * 1e3:.3f}")
    fell = None
    while time.monotonic() - t0 < 5.0:
        if value(DRIVE_ENABLE) == 0:
            fell = time.monotonic()
            break
    if fell is None:
        print("drive_enable_fell=no")
    else:
        print(f"drive_enable_fell=yes after_ms={(fell - t0) * 1e3:.3f} "
              f"after_periods={(fell - t0) / period:.2f}")
    # Released e-stop: the line must stay low, the lamp lit, for the rest of the run.
    rearmed = 0
    samples = 0
    lamp_off = 0
    watch_until = time.monotonic() + 1.0
    while time.monotonic() < watch_until and trainer.poll() is None:
        rearmed += value(DRIVE_ENABLE)
        lamp_off += 1 - value(FAULT_LAMP)
        samples += 1
        time.sleep(0.002)
    print(f"after_release samples={samples} drive_enable_high={rearmed} fault_lamp_off={lamp_off}")
    status = trainer.wait(timeout=120)
    print(f"trainer_exit={status}")
    if simdrive is not None:
        simdrive.send_signal(2)
        print(f"simdrive_exit={simdrive.wait(timeout=30)}")
    # The trainer released its lines: gpio-sim outputs revert to their pull (down).
    print(f"after_exit drive_enable={value(DRIVE_ENABLE)}")
    chip_sh("remove", "trainer")
    return 0


if __name__ == "__main__":
    sys.exit(main())
