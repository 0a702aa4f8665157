#!/usr/bin/env python3
"""End to end: the real trainer (simulated bench, real time, 2 s) under a fake systemd. The test
owns the NOTIFY_SOCKET datagram socket and sets WATCHDOG_USEC; it checks READY=1 comes first,
then WATCHDOG=1 at about half the watchdog period while the loop runs, then STOPPING=1, and
that the run itself ended cleanly.
usage: trainer_notify_test.py TRAINER_BINARY REPO_DIR"""
import os
import socket
import subprocess
import sys
import tempfile
import time

trainer, repo = sys.argv[1], sys.argv[2]
WATCHDOG_USEC = 400_000  # pings due every 0.2 s
RUN_S = 2.0

with tempfile.TemporaryDirectory() as work:
    path = os.path.join(work, "notify.sock")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(path)
    sock.settimeout(0.2)
    env = dict(os.environ, NOTIFY_SOCKET=path, WATCHDOG_USEC=str(WATCHDOG_USEC))
    env.pop("WATCHDOG_PID", None)
    started = time.monotonic()
    proc = subprocess.Popen(
        [trainer, "--scene", os.path.join(repo, "config/scenes/wall.toml"), "--hal", "sim",
         "--seconds", str(RUN_S), "--no-rt"],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    messages = []  # (seconds since start, text)
    while True:
        try:
            data = sock.recv(4096)
            messages.append((time.monotonic() - started, data.decode()))
        except socket.timeout:
            if proc.poll() is not None:
                break
    output = proc.stdout.read()
    if proc.returncode != 0:
        sys.exit(f"trainer exited with {proc.returncode}:\n{output}")

kinds = [text.split("\n")[0] for _, text in messages]
print("messages:", [(round(t, 3), text.replace("\n", " | ")) for t, text in messages])
assert kinds and kinds[0] == "READY=1", f"READY=1 is not first: {kinds}"
assert "STATUS=armed scene wall" in messages[0][1], messages[0][1]
assert kinds[-1] == "STOPPING=1", f"STOPPING=1 is not last: {kinds}"
assert kinds.count("READY=1") == 1 and kinds.count("STOPPING=1") == 1, kinds
pings = [t for (t, text) in messages if text == "WATCHDOG=1"]
ready_at = messages[0][0]
stopping_at = messages[-1][0]
assert all(ready_at <= t <= stopping_at for t in pings), "a ping outside READY..STOPPING"
# One ping at READY's first tick, then one per 0.2 s (checked on a 33 ms supervisor tick):
# about (STOPPING - READY) / 0.2 (~10: a loaded machine stretches the 2000 cycles of a 2 s
# run when cycles overrun); allow it to lose a few.
expected = (stopping_at - ready_at) / (WATCHDOG_USEC / 2e6)
assert 0.5 * expected <= len(pings) <= expected + 2, f"{len(pings)} pings, expected ~{expected:.0f}"
gaps = [b - a for a, b in zip(pings, pings[1:])]
assert min(gaps) >= 0.2 - 0.02, f"pings closer than half the watchdog period: {min(gaps):.3f} s"
print(f"READY at {ready_at:.3f} s, {len(pings)} WATCHDOG pings (gaps {min(gaps):.3f}.."
      f"{max(gaps):.3f} s), STOPPING at {stopping_at:.3f} s")
