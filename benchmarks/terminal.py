"""How soon the terminal answers, on a busy machine: `deepphy --version` and the first line
of `deepphy run` (on a terminal: a pty), side by side with `python -c pass`, while 3 CPU
hogs (`while True: pass`, at the commands' own priority) keep the cores busy.

Each round runs the three commands once, in turn (so a round's load is shared); the first
round only warms the caches (bytecode, the page cache) and is not counted. Prints each
command's median and its ratio to the bare interpreter's, and the load average.

    .venv/bin/python benchmarks/terminal.py [--rounds 15] [--hogs 3]

Target (issue 43): the first line within 2x of `python -c pass`.
"""

from __future__ import annotations

import argparse
import os
import pty
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def until_exit(cmd: list[str], env: dict[str, str]) -> float:
    t0 = time.monotonic()
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, check=True)
    return time.monotonic() - t0


def first_output(cmd: list[str], env: dict[str, str], on_terminal: bool) -> float:
    """Seconds from the start to the command's first byte (stderr on a pty if
    `on_terminal`, else stdout); the command is then killed."""
    master, terminal = pty.openpty() if on_terminal else os.pipe()
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL if on_terminal else terminal,
                            stderr=terminal if on_terminal else subprocess.DEVNULL, env=env)
    os.close(terminal)
    try:
        first = os.read(master, 1)
        took = time.monotonic() - t0
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.send_signal(signal.SIGKILL)  # a run killed before it wrote anything: nothing to resume
        proc.wait()
    if not first:
        sys.exit(f"{' '.join(cmd)} said nothing")
    return took


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--hogs", type=int, default=3)
    args = ap.parse_args()

    python = sys.executable
    script = Path(python).with_name("deepphy")  # the console script a user runs
    deepphy = [str(script)] if script.exists() else [python, "-m", "deepphy.cli"]
    env = {k: v for k, v in os.environ.items() if k not in ("RAY_ADDRESS", "PYTHONDONTWRITEBYTECODE")}
    out = Path(tempfile.mkdtemp(prefix="deepphy-terminal-"))
    commands = {
        "python -c pass": lambda: until_exit([python, "-c", "pass"], env),
        "deepphy --version": lambda: first_output([*deepphy, "--version"], env, on_terminal=False),
        "deepphy run: first line": lambda i: first_output(
            [*deepphy, "run", "--tasks", "support", "--runs", "1", "--out", str(out / f"run{i}")], env,
            on_terminal=True),
    }
    hogs = [subprocess.Popen([python, "-c", "while True: pass"]) for _ in range(args.hogs)]
    times: dict[str, list[float]] = {name: [] for name in commands}
    try:
        time.sleep(2)  # the hogs have the cores
        load_before = os.getloadavg()
        for i in range(args.rounds + 1):
            for name, command in commands.items():
                took = command(i) if name.startswith("deepphy run") else command()
                if i:  # round 0 warms up
                    times[name].append(took)
        load_after = os.getloadavg()
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
        shutil.rmtree(out, ignore_errors=True)
    bare = statistics.median(times["python -c pass"])
    print(f"{args.hogs} CPU hogs on {os.cpu_count()} CPUs; load average {load_before[0]:.1f} at the start, "
          f"{load_after[0]:.1f} at the end; {args.rounds} rounds")
    for name, values in times.items():
        med = statistics.median(values)
        print(f"  {name:26} median {med * 1000:7.0f} ms  (min {min(values) * 1000:.0f}, max {max(values) * 1000:.0f})"
              f"  {med / bare:4.2f}x python -c pass")


if __name__ == "__main__":
    main()
