"""Time to a first result: `deepphy run --env ENV --limit 2 --runs 1` from the command.

Prints, per try, the seconds from the command's start to its first line of output, to
its first live progress line (the run's own figures, after Ray and the workers are up),
to its first record in attempts.jsonl, and to its exit. Each try starts a fresh process
and a fresh local Ray (the machine's caches, e.g. compiled Pooltool/Kinetix kernels, stay
as they are: a warm machine unless they were cleared).

    .venv/bin/python benchmarks/first_result.py [--env iphyre] [--tries 3] [--quick]

Targets (issue 25, on a warm machine): first line within 2 s, first record within 8 s.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time


def one_try(env: str, out: str) -> dict[str, float]:
    environ = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    cmd = [sys.executable, "-m", "deepphy.cli", "run", "--env", env, "--model", "mock", "--limit", "2",
           "--runs", "1", "--out", out]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=environ)
    seen: dict[str, float] = {}
    lines: list[str] = []

    def read() -> None:
        for raw in proc.stdout:
            line = raw.decode(errors="replace").rstrip()
            lines.append(line)
            now = time.monotonic() - t0
            seen.setdefault("first line", now)
            if "attempts" in line and "deepphy:" not in line:  # the live progress line (figures)
                seen.setdefault("first progress", now)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    records = os.path.join(out, "attempts.jsonl")
    while proc.poll() is None:
        if "first record" not in seen and os.path.exists(records) and os.path.getsize(records) > 0:
            seen["first record"] = time.monotonic() - t0
        time.sleep(0.02)
    seen["exit"] = time.monotonic() - t0
    reader.join(5)
    if proc.returncode != 0:
        sys.exit(f"the run failed ({proc.returncode}):\n" + "\n".join(lines[-20:]))
    seen.setdefault("first record", seen["exit"])  # written in the last moments
    return seen


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="iphyre")
    ap.add_argument("--tries", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="one try")
    a = ap.parse_args()
    tries = 1 if a.quick else a.tries
    print(f"load {os.getloadavg()[0]:.2f} (1-min) at the start")
    keys = ("first line", "first progress", "first record", "exit")
    results = []
    for i in range(tries):
        with tempfile.TemporaryDirectory(prefix="dpfirst") as tmp:
            seen = one_try(a.env, os.path.join(tmp, "run"))
        results.append(seen)
        print(f"try {i + 1}: " + ", ".join(f"{k} {seen[k]:.1f} s" for k in keys if k in seen))
    print("median: " + ", ".join(
        f"{k} {statistics.median(r[k] for r in results if k in r):.1f} s" for k in keys if any(k in r for r in results))
        + "  (targets: first line <= 2 s, first record <= 8 s)")
    print(f"load {os.getloadavg()[0]:.2f} (1-min) at the end")


if __name__ == "__main__":
    main()
