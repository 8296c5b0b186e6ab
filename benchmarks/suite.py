"""A suite as one command vs its cells as separate `deepphy run` commands, one after
another: wall time of each way, and the records of every cell compared (they must be
equal, timings and provider facts aside).

The suite runs its cells interleaved in one Ray runtime (started once): cells of up to two
environment settings at once, the cells of one setting sharing its environment workers;
separate commands start Ray and the workers per cell, one cell after another. Target:
>= 1.5x faster as a suite on 2 cores. Prints the load (`uptime`) before and after: timings
on a shared machine depend on it.

    uv run python benchmarks/suite.py [SUITE_FILE]   (default: a MOCK suite over the six
                                                      environments, 2 tasks each, VLA and WM, 1 run)
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from deepphy.runs.store import read_records
from deepphy.suite import cells, load_suite

DEFAULT = {
    "name": "bench",
    "envs": [{"env": "phyre", "limit": 2}, {"env": "iphyre", "limit": 2}, {"env": "kinetix", "limit": 2},
             {"env": "pooltool", "limit": 2}, {"env": "angrybirds", "limit": 2}, {"env": "cuttherope", "limit": 2}],
    "formats": ["vla", "wm"],
    "runs": 1,
    "seed": 0,
}
DEEPPHY = [sys.executable, "-m", "deepphy.cli"]


def views(path: Path) -> list[dict]:
    return sorted((r.deterministic_view() for r in read_records(path)), key=lambda v: (v["task"], v["run"], v["attempt"]))


def timed(argv: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def load() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def main() -> None:
    print(f"load before: {load()}", flush=True)
    with tempfile.TemporaryDirectory(prefix="deepphy-suite-bench-") as tmp:
        tmp = Path(tmp)
        if len(sys.argv) > 1:
            suite_file = Path(sys.argv[1])
        else:
            suite_file = tmp / "bench.yaml"
            suite_file.write_text(yaml.safe_dump(DEFAULT))
        grid = cells(load_suite(str(suite_file)))
        suite_s = timed([*DEEPPHY, "run", "--suite", str(suite_file), "--out", str(tmp / "suite"), "--no-progress"])
        print(f"suite: {len(grid)} cells in one command: {suite_s:.1f} s (load after: {load()})", flush=True)
        separate_s = 0.0
        for cell in grid:
            c = cell.config
            argv = [*DEEPPHY, "run", "--env", c.env, "--model", c.model, "--format", c.format.value,
                    "--runs", str(c.runs), "--seed", str(c.seed), "--out", str(tmp / "separate" / cell.dir),
                    "--no-progress"]
            argv += ["--tasks", ",".join(c.tasks)] if c.tasks else []
            argv += ["--limit", str(c.limit)] if c.limit else []
            argv += ["--max-attempts", str(c.max_attempts)] if c.max_attempts else []
            for key, value in c.env_options.items():
                argv += ["--env-option", f"{key}={yaml.safe_dump(value).splitlines()[0]}"]
            took = timed(argv)
            separate_s += took
            same = views(tmp / "suite" / cell.dir) == views(tmp / "separate" / cell.dir)
            print(f"  {cell.dir}: {took:.1f} s as its own command; records equal to the suite's: {same}", flush=True)
            assert same, cell.dir
        print(f"separate commands: {separate_s:.1f} s; suite / separate: {suite_s / separate_s:.2f} "
              f"({separate_s / suite_s:.2f}x faster as a suite); load after: {load()}")


if __name__ == "__main__":
    main()
