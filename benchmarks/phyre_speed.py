"""PHYRE on Box2D: data decoding, simulation speed and the random agent, in one process.

- decode: the first-use decode of `tasks.bin.lzma` (Thrift -> tasks -> the JSON cache),
  timed on a copy of the cached data file in a temporary cache; then reading the cache in
  a fresh process (what every later process pays);
- simulation: ms per valid simulation for random grid actions (the paper's 5 x 5 x 5) on
  the default evaluation set, with and without the exact early stops, and ms per env step
  (simulation + key-frame strip + PNG);
- random agent: a uniformly random grid action per attempt (no memory, invalid attempts
  counted), 10 attempts per task, over the default 1000 tasks: the fraction solved, the
  mean over `--seeds` seeds.

The random agent needs every grid action's status on every task (~112,000 actions, the
bulk of the time); `--report FILE` takes them from a solvability report instead
(`deepphy solve --env phyre report --out FILE`).

Usage: .venv/bin/python benchmarks/phyre_speed.py [--sims 300] [--seeds 3] [--agent-tasks 1000] [--report FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def decode_times() -> tuple[list[float], list[float]]:
    """(import s, task list s) of a fresh process on an empty cache, then on the filled one."""
    from deepphy.envs.phyre import data

    source = data.ensure_data_file()
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "phyre").mkdir()
        shutil.copy(source, Path(tmp) / "phyre" / "tasks.bin.lzma")
        code = ("import time; t = time.perf_counter(); from deepphy.envs.phyre import data; "
                "u = time.perf_counter(); data.task_ids(); print(u - t, time.perf_counter() - u)")
        env = {**os.environ, "DEEPPHY_CACHE_DIR": tmp}

        def run() -> list[float]:
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
            return [float(v) for v in out.stdout.split()]

        cold = run()
        warm = run()
    return cold, warm


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sims", type=int, default=300, help="valid simulations timed")
    ap.add_argument("--seeds", type=int, default=3, help="random-agent repetitions")
    ap.add_argument("--agent-tasks", type=int, default=1000, help="tasks for the random agent (first N)")
    ap.add_argument("--report", help="a solvability report (grid5) with every grid action's status")
    args = ap.parse_args()

    cold, warm = decode_times()
    print(f"fresh process: import deepphy.envs.phyre {warm[0]:.2f} s; task list from tasks.bin.lzma (first use: "
          f"decode and write the cache) {cold[1]:.2f} s; from the cache {warm[1]:.2f} s")

    from deepphy.envs.phyre import data, sim
    from deepphy.envs.phyre.env import PhyreEnv, PhyreOptions
    from deepphy.envs.phyre.env import SPACES
    from deepphy.envs.phyre.space import InvalidPlacement

    tasks = PhyreEnv.tasks(PhyreOptions())
    space = SPACES["grid5"]
    actions = space.all_actions()
    rng = np.random.default_rng(0)
    placed = []
    while len(placed) < args.sims:
        task = data.load_task(tasks[int(rng.integers(len(tasks)))].params["phyre_id"])
        try:
            placed.append((task, sim.place(task, *space.to_phyre(actions[int(rng.integers(len(actions)))]))))
        except InvalidPlacement:
            pass
    for early in (True, False):
        t = time.perf_counter()
        steps = sum(sim.simulate(task, ball, early_stop=early).simulated for task, ball in placed)
        ms = (time.perf_counter() - t) * 1000 / len(placed)
        print(f"valid simulation ({'exact early stops' if early else 'every step'}): {ms:.2f} ms "
              f"({steps / len(placed):.0f} steps on average)")
    env = PhyreEnv()
    t = time.perf_counter()
    n = 0
    for task, _ in placed[:100]:
        env.reset(next(x for x in tasks if x.params["phyre_id"] == task.id))
        for a in actions[::25]:
            env.step(a)
            n += 1
    print(f"env step (place, simulate, key-frame strip, PNG; invalid ones included): "
          f"{(time.perf_counter() - t) * 1000 / n:.2f} ms")

    # The random agent: statuses of all grid actions per distinct task, then sampled attempts.
    distinct = sorted({t.params["phyre_id"] for t in tasks[: args.agent_tasks]})
    t = time.perf_counter()
    if args.report:
        rows = json.loads(Path(args.report).read_text())["tasks"]
        statuses = {r["phyre_id"]: np.array(r["statuses"]) for r in rows if r["phyre_id"] in distinct}
        assert len(statuses) == len(distinct), "the report does not cover these tasks"
    else:
        from deepphy.envs.phyre.solve import grid_statuses

        statuses = {pid: np.array(grid_statuses(data.load_task(pid), space)) for pid in distinct}
    print(f"all {len(actions)} grid actions on {len(distinct)} distinct tasks: {time.perf_counter() - t:.0f} s; "
          f"invalid {np.mean([(s == 0).mean() for s in statuses.values()]):.1%}, "
          f"solvable {np.mean([(s == 1).any() for s in statuses.values()]):.1%}")
    rates = []
    for seed in range(args.seeds):
        agent = np.random.default_rng(seed)
        solved = [(statuses[t.params["phyre_id"]][agent.integers(len(actions), size=10)] == 1).any()
                  for t in tasks[: args.agent_tasks]]
        rates.append(np.mean(solved))
    print(f"random agent, 10 attempts, {min(args.agent_tasks, len(tasks))} tasks: solved "
          f"{np.mean(rates):.1%} (seeds: {', '.join(f'{r:.1%}' for r in rates)})")


if __name__ == "__main__":
    main()
