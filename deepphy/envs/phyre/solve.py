"""Solvability of the PHYRE evaluation set: which tasks the grid actions (can) solve.

    deepphy solve --env phyre report [--json FILE] [--setup both] [--fold 0]
        [--split test] [--actions grid5] [--continuous N] [--jobs J] [--limit N]

For every distinct PHYRE task of the selected set: simulate every action of the grid
(grid5: 5 x 5 cells x 5 radii = 125), count the invalid and the solving ones; with
`--continuous N`, tasks no grid action solves get up to N random valid continuous actions
(seeded by the task id) until one solves. Prints the summary; with `--json FILE`, also
writes the JSON report there (per task, per setup and template, overall); nothing is
written by default. The expected success of a uniformly random grid agent within 10
attempts (invalid attempts counted, with and without repeats) follows exactly from the
per-task counts.

`main(argv)` is the entry point (wired to `deepphy solve --env phyre`).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from math import comb
from pathlib import Path

import numpy as np

from deepphy.seeding import seeded_rng
from deepphy.envs.phyre import data, sim
from deepphy.envs.phyre.env import SPACES, PhyreEnv, PhyreOptions
from deepphy.envs.phyre.space import InvalidPlacement, PhyreSpace

RANDOM_AGENT_ATTEMPTS = 10  # the paper's K


def grid_statuses(task: data.PhyreTask, space: PhyreSpace) -> list[int]:
    """PHYRE's status per grid action, in `space.all_actions()` order: 1 solved, -1 not, 0 invalid."""
    out = []
    for action in space.all_actions():
        try:
            ball = sim.place(task, *space.to_phyre(action))
        except InvalidPlacement:
            out.append(0)
            continue
        out.append(1 if sim.simulate(task, ball).solved else -1)
    return out


def continuous_search(task: data.PhyreTask, budget: int) -> tuple[list[float] | None, int]:
    """(first solving action (x, y, r) found, valid simulations run) over random actions."""
    rng = seeded_rng("phyre-continuous-search", task.id)
    sims = tries = 0
    while sims < budget and tries < 50 * budget:
        tries += 1
        action = [round(float(v), 4) for v in rng.random(3)]
        try:
            ball = sim.place(task, *action)
        except InvalidPlacement:
            continue
        sims += 1
        if sim.simulate(task, ball).solved:
            return action, sims
    return None, sims


def _solve_one(args: tuple[str, str, int]) -> dict:
    phyre_id, actions, budget = args
    task = data.load_task(phyre_id)
    space = SPACES[actions]
    t0 = time.perf_counter()
    statuses = grid_statuses(task, space)
    solving = [space.format(a) for a, s in zip(space.all_actions(), statuses) if s == 1]
    found, sims = (None, 0)
    if not solving and budget:
        found, sims = continuous_search(task, budget)
    return {
        "phyre_id": phyre_id, "template": task.template, "statuses": statuses,
        "invalid_grid_actions": statuses.count(0), "solving_grid_actions": len(solving), "solving": solving,
        "continuous_solution": found, "continuous_simulations": sims,
        "seconds": round(time.perf_counter() - t0, 3),
    }


def random_agent_success(solving: int, total: int, attempts: int = RANDOM_AGENT_ATTEMPTS) -> tuple[float, float]:
    """P(solved within `attempts`) for a uniform random grid agent: (with repeats, without)."""
    with_repeats = 1 - (1 - solving / total) ** attempts
    without = 1 - comb(total - solving, attempts) / comb(total, attempts) if attempts <= total else float(solving > 0)
    return with_repeats, without


def _summary(rows: list[dict], n_actions: int) -> dict:
    counts = np.array([r["solving_grid_actions"] for r in rows])
    invalid = np.array([r["invalid_grid_actions"] for r in rows])
    agent = np.array([random_agent_success(int(c), n_actions) for c in counts]) if len(rows) else np.zeros((0, 2))
    return {
        "tasks": len(rows),
        "solvable_on_grid": int((counts > 0).sum()),
        "fraction_solvable_on_grid": round(float((counts > 0).mean()), 4) if rows else 0.0,
        "mean_solving_grid_actions": round(float(counts.mean()), 3) if rows else 0.0,
        "fraction_of_grid_actions_invalid": round(float(invalid.sum() / (len(rows) * n_actions)), 4) if rows else 0.0,
        "random_agent_success_at_10": round(float(agent[:, 0].mean()), 4) if rows else 0.0,
        "random_agent_success_at_10_no_repeats": round(float(agent[:, 1].mean()), 4) if rows else 0.0,
        "solvable_with_continuous_search": int(sum(r["solving_grid_actions"] > 0 or r["continuous_solution"] is not None
                                                   for r in rows)),
    }


def report(out: Path | None, options: PhyreOptions, jobs: int, budget: int, limit: int | None) -> dict:
    space = SPACES[options.actions]
    if not isinstance(space, PhyreSpace):
        raise SystemExit("solve: --actions must be a grid (grid5 or grid8)")
    tasks = PhyreEnv.tasks(options)[:limit]
    distinct = sorted({t.params["phyre_id"] for t in tasks})
    t0 = time.time()
    work = [(pid, options.actions, budget) for pid in distinct]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as pool:
            results = list(pool.map(_solve_one, work, chunksize=4))
    else:
        results = [_solve_one(w) for w in work]
    by_id = {r["phyre_id"]: r for r in results}
    rows = [{"task": t.id, "group": t.group, **by_id[t.params["phyre_id"]]} for t in tasks]
    n_actions = len(space.all_actions())
    summary = {
        "setup": options.setup, "fold": options.fold, "split": options.split,
        "grid": f"{space.grid}x{space.grid} cells x {space.radius_levels} radii = {n_actions} actions",
        **_summary(rows, n_actions),
        "by_setup": {},
        "seconds": round(time.time() - t0, 1),
    }
    for group in sorted({r["group"] for r in rows}):
        in_group = [r for r in rows if r["group"] == group]
        per_template = {tpl: _summary([r for r in in_group if r["template"] == tpl], n_actions)
                        for tpl in sorted({r["template"] for r in in_group})}
        summary["by_setup"][group] = {**_summary(in_group, n_actions), "by_template": per_template}
    result = {"summary": summary, "actions": [space.format(a) for a in space.all_actions()], "tasks": rows}
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(result, indent=1) + "\n")
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="deepphy solve --env phyre", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    rep = sub.add_parser("report", help="solvability of the evaluation set by the grid actions")
    rep.add_argument("--json", "--out", dest="json", metavar="FILE", help="also write the report as JSON to this file")
    rep.add_argument("--setup", default="both", choices=["within", "cross", "both"])
    rep.add_argument("--fold", type=int, default=0)
    rep.add_argument("--split", default="test", choices=["train", "dev", "test"])
    rep.add_argument("--actions", default="grid5", choices=["grid5", "grid8"])
    rep.add_argument("--continuous", type=int, default=0, metavar="N",
                     help="random valid continuous actions to try on tasks no grid action solves")
    rep.add_argument("--limit", type=int, default=None, help="only the first N tasks")
    rep.add_argument("--jobs", type=int, default=max(1, (os.cpu_count() or 2) - 1))
    args = parser.parse_args(argv)
    options = PhyreOptions(setup=args.setup, fold=args.fold, split=args.split, actions=args.actions)
    s = report(Path(args.json) if args.json else None, options, args.jobs, args.continuous, args.limit)["summary"]
    print(f"{s['tasks']} tasks ({s['setup']}, fold {s['fold']}, {s['split']}); {s['grid']}; "
          f"solvable on the grid: {s['solvable_on_grid']} ({100 * s['fraction_solvable_on_grid']:.1f}%); "
          f"invalid grid actions {100 * s['fraction_of_grid_actions_invalid']:.1f}%; random agent within "
          f"{RANDOM_AGENT_ATTEMPTS} attempts {100 * s['random_agent_success_at_10']:.1f}%; {s['seconds']} s")
    if args.continuous:
        print(f"  solvable with the continuous search: {s['solvable_with_continuous_search']}/{s['tasks']}")
    for group, g in s["by_setup"].items():
        templates = ", ".join(f"{tpl} {v['solvable_on_grid']}/{v['tasks']}" for tpl, v in g["by_template"].items())
        print(f"  {group}: {g['solvable_on_grid']}/{g['tasks']} solvable on the grid; per template: {templates}")
    if args.json:
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
