"""CPU time of the watchdog (deepphy/reaper.py) of a local `deepphy run`, per attempt.

Runs `deepphy run --env iphyre --model mock` on a new local Ray instance, samples the
watchdog process's CPU time (user + system) until it exits, and prints it per attempt
recorded. The machine's load and process count are printed with it: the old watchdog's
cost grew with the number of processes on the machine.

    .venv/bin/python benchmarks/watchdog_cpu.py [--runs 3] [--limit 40]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import psutil


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--limit", type=int, default=40, help="I-PHYRE games (40: all)")
    a = ap.parse_args()
    out = os.path.join(tempfile.mkdtemp(prefix="dpwatch"), "run")
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    load = os.getloadavg()[0]
    n_procs = len(psutil.pids())
    t0 = time.monotonic()
    driver = subprocess.Popen(
        [sys.executable, "-m", "deepphy.cli", "run", "--env", "iphyre", "--model", "mock", "--runs", str(a.runs),
         "--limit", str(a.limit), "--out", out, "--no-progress"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    watchdog, cpu = None, 0.0
    while driver.poll() is None or (watchdog is not None and watchdog.is_running()):
        if watchdog is None and driver.poll() is None:
            try:
                watchdog = next((p for p in psutil.Process(driver.pid).children()
                                 if "deepphy.reaper" in " ".join(p.cmdline())), None)
            except psutil.Error:
                pass
        if watchdog is not None:
            try:
                times = watchdog.cpu_times()
                cpu = times.user + times.system
            except psutil.Error:
                break
        time.sleep(0.05)
    wall = time.monotonic() - t0
    if driver.returncode != 0:
        sys.exit(f"the run failed: {driver.stderr.read().decode()[-2000:]}")
    with open(os.path.join(out, "attempts.jsonl"), "rb") as f:
        attempts = sum(1 for _ in f)
    print(f"load {load:.1f} (1-min average) and {n_procs} processes at the start; run of {wall:.0f} s, "
          f"{attempts} attempts")
    if watchdog is None:
        print("no watchdog process was seen")
        return
    print(f"watchdog CPU: {cpu * 1000:.0f} ms in all, {cpu / attempts * 1000:.3f} ms per attempt "
          f"(last sample before it exited)")


if __name__ == "__main__":
    main()
