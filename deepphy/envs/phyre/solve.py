"""Solvability of PHYRE tasks: search for solving placements, verify generated variants.

    python -m deepphy.envs.phyre.solve report [--out FILE] [--jobs N] [--splits within,cross]
        For every task of the evaluation set: simulate all grid actions (default 5x5
        cells x 5 radii = 125), count the solving ones; when none solves, run the
        continuous search (a 64 x 64 x 16 lattice of (x, y, r) visited in a seeded random
        order, stopping at the first solution). Writes a JSON report (per task: number of
        solving grid actions, the solving actions, a continuous solution) and prints the
        summary.

    python -m deepphy.envs.phyre.solve generate [--templates 0,1,...] [--jobs N]
        Offline, once per template change: for each variant pick the first sub-seed whose
        scene (a) is not solved without a ball, stays stable and in the scene, and (b) has
        a solving placement in the continuous space. Writes `templates/variants.json`
        (sub-seed and one solving placement per variant). `tasks()` never simulates.

`main(argv)` is the entry point (wired to `deepphy solve --env phyre`).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Iterable

import numpy as np

from deepphy.seeding import seeded_rng
from deepphy.envs.phyre import scene as S
from deepphy.envs.phyre.space import PhyreSpace

CONT_XY = 64  # continuous search lattice: 64 x 64 positions ...
CONT_R = 16  # ... x 16 radii from r_min to r_max
MAX_SUB_SEEDS = 200


def no_action_problem(scene: S.Scene) -> str | None:
    """Why a scene is unusable without any ball placed (None when fine)."""
    o = S.simulate(scene)
    if o.success:
        return "solved without a ball"
    if o.reason == "exploded" or o.max_speed > 600:
        return f"unstable (max speed {o.max_speed:.0f} px/s)"
    if o.left_scene:
        return "an object left the scene"
    return None


def grid_results(scene: S.Scene, space: PhyreSpace) -> tuple[list[str], int]:
    """(solving actions as text, number of valid actions) over every grid action."""
    solving, valid = [], 0
    for a in space.all_actions():
        x, y, r = space.to_scene(a)
        if S.placement_problem(scene, x, y, r) is not None:
            continue
        valid += 1
        if S.simulate(scene, (x, y, r)).success:
            solving.append(space.format(a))
    return solving, valid


def continuous_candidates(key: Iterable, r_min: float = 2.0, r_max: float = 32.0, limit: int | None = None):
    """A seeded random order over the continuous lattice (x, y, r)."""
    rng = seeded_rng("phyre-continuous", *key)
    n = CONT_XY * CONT_XY * CONT_R
    order = rng.permutation(n)[:limit]
    for idx in order:
        ix, rest = divmod(int(idx), CONT_XY * CONT_R)
        iy, ir = divmod(rest, CONT_R)
        x = (ix + 0.5) * S.W / CONT_XY
        y = (iy + 0.5) * S.H / CONT_XY
        r = r_min + (r_max - r_min) * ir / (CONT_R - 1)
        yield x, y, r


def continuous_search(scene: S.Scene, key: Iterable, limit: int | None = None,
                      first: tuple | None = None) -> tuple[tuple[float, float, float] | None, int]:
    """(first solving placement found, simulations run)."""
    sims = 0
    cands = continuous_candidates(key, limit=limit)
    if first is not None:
        cands = iter([first, *cands])
    for x, y, r in cands:
        if S.placement_problem(scene, x, y, r) is not None:
            continue
        sims += 1
        if S.simulate(scene, (x, y, r)).success:
            return (round(x, 3), round(y, 3), round(r, 3)), sims
    return None, sims


# -- generate ---------------------------------------------------------------------------


def _generate_one(args: tuple[int, int, int]) -> tuple[int, int, list | None, str]:
    from deepphy.envs.phyre.templates import Skip, build_with_seed

    template, variant, budget = args
    space = PhyreSpace()
    grid = [space.to_scene(a) for a in space.all_actions()]
    notes = []
    for k in range(MAX_SUB_SEEDS):
        try:
            scene = build_with_seed(template, variant, k)
        except Skip:
            continue
        problem = no_action_problem(scene)
        if problem:
            notes.append(problem)
            continue
        rng = seeded_rng("phyre-generate", template, variant, k)
        # Grid actions first (in random order), then the continuous lattice.
        for i in rng.permutation(len(grid)):
            x, y, r = grid[int(i)]
            if S.placement_problem(scene, x, y, r) is None and S.simulate(scene, (x, y, r)).success:
                return template, variant, [k, [x, y, r]], ""
        sol, _ = continuous_search(scene, (template, variant, k), limit=budget)
        if sol is not None:
            return template, variant, [k, list(sol)], ""
        notes.append("no solution found")
    return template, variant, None, "; ".join(sorted(set(notes)))


def generate(templates_: list[int], jobs: int, budget: int) -> None:
    from deepphy.envs.phyre.templates import VARIANTS, VARIANTS_FILE

    data = json.loads(VARIANTS_FILE.read_text()) if VARIANTS_FILE.exists() else {}
    data.setdefault("about", "accepted sub-seed and one verified solving placement [x, y, r] (px, y up) per "
                             "variant; written by `python -m deepphy.envs.phyre.solve generate`")
    store = data.setdefault("templates", {})
    t0 = time.time()
    with ProcessPoolExecutor(jobs) as pool:
        for t in templates_:
            entries: list = [None] * VARIANTS
            for _, v, entry, note in pool.map(_generate_one, [(t, v, budget) for v in range(VARIANTS)]):
                entries[v] = entry
                if entry is None:
                    print(f"template {t:02d} variant {v:02d}: FAILED ({note})", file=sys.stderr)
            store[str(t)] = entries
            seeds = [e[0] for e in entries if e is not None]
            print(f"template {t:02d}: {len(seeds)}/{VARIANTS} verified, mean sub-seed {np.mean(seeds):.1f}, "
                  f"{time.time() - t0:.0f} s", flush=True)
            data["templates"] = {k: store[k] for k in sorted(store, key=int)}
            VARIANTS_FILE.write_text(json.dumps(data, separators=(",", ":")).replace("],[", "],\n[") + "\n")
    print(f"wrote {VARIANTS_FILE} in {time.time() - t0:.0f} s")


# -- report -----------------------------------------------------------------------------


def _report_one(args: tuple[str, int, int, dict, int]) -> dict:
    from deepphy.envs.phyre.templates import variant_scene, verified_solution

    task_id, template, variant, space_json, budget = args
    space = PhyreSpace(**space_json)
    scene = variant_scene(template, variant)
    t0 = time.time()
    solving, valid = grid_results(scene, space)
    sims = valid
    cont = None
    if not solving:
        cont, n = continuous_search(scene, (template, variant), limit=budget, first=verified_solution(template, variant))
        sims += n
    return {
        "task": task_id, "template": template, "variant": variant, "valid_grid_actions": valid,
        "solving_grid_actions": len(solving), "solving": solving,
        "continuous_solution": list(cont) if cont else None,
        "solvable": bool(solving or cont), "simulations": sims, "seconds": round(time.time() - t0, 3),
    }


def report(out: Path, jobs: int, splits: str, fold: int, budget: int, limit: int | None) -> dict:
    from deepphy.envs.phyre.env import PhyreEnv, PhyreOptions

    options = PhyreOptions(splits=splits, fold=fold)
    space = PhyreEnv(options).space
    tasks = PhyreEnv.tasks(options)[:limit]
    seen: dict[tuple[int, int], dict] = {}
    work = []
    for t in tasks:
        key = (t.params["template"], t.params["variant"])
        if key not in seen:
            seen[key] = {}
            work.append((t.id, key[0], key[1], space.model_dump(exclude={"kind"}), budget))
    t0 = time.time()
    with ProcessPoolExecutor(jobs) as pool:
        for row in pool.map(_report_one, work, chunksize=4):
            seen[(row["template"], row["variant"])] = row
    rows = []
    for t in tasks:
        row = dict(seen[(t.params["template"], t.params["variant"])])
        row["task"], row["group"] = t.id, t.group
        rows.append(row)
    n = len(rows)
    counts = np.array([r["solving_grid_actions"] for r in rows])
    total_grid = space.num_cells * space.radius_levels
    summary = {
        "tasks": n,
        "grid": f"{space.grid}x{space.grid} cells x {space.radius_levels} radii = {total_grid} actions",
        "solvable_on_grid": int((counts > 0).sum()),
        "fraction_solvable_on_grid": round(float((counts > 0).mean()), 4) if n else 0.0,
        "mean_solving_grid_actions": round(float(counts.mean()), 3) if n else 0.0,
        "mean_solving_grid_actions_when_solvable": round(float(counts[counts > 0].mean()), 3) if (counts > 0).any() else 0.0,
        "fraction_of_grid_actions_solving": round(float(counts.sum() / (n * total_grid)), 4) if n else 0.0,
        "solvable_in_continuous_space": int(sum(r["solvable"] for r in rows)),
        "unsolved": [r["task"] for r in rows if not r["solvable"]],
        "by_group": {},
        "by_template": {},
        "seconds": round(time.time() - t0, 1),
    }
    for g in sorted({r["group"] for r in rows}):
        c = np.array([r["solving_grid_actions"] for r in rows if r["group"] == g])
        summary["by_group"][g] = {"tasks": len(c), "fraction_solvable_on_grid": round(float((c > 0).mean()), 4),
                                  "mean_solving_grid_actions": round(float(c.mean()), 3)}
    for t in sorted({r["template"] for r in rows}):
        c = np.array([r["solving_grid_actions"] for r in rows if r["template"] == t])
        summary["by_template"][f"{t:02d}"] = {"tasks": len(c), "fraction_solvable_on_grid": round(float((c > 0).mean()), 3),
                                              "mean_solving_grid_actions": round(float(c.mean()), 2)}
    result = {"summary": summary, "tasks": rows}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m deepphy.envs.phyre.solve", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    rep = sub.add_parser("report", help="solvability of the evaluation set (grid + continuous search)")
    rep.add_argument("--out", default="phyre_solvability.json")
    rep.add_argument("--splits", default="within,cross")
    rep.add_argument("--fold", type=int, default=0)
    rep.add_argument("--limit", type=int, default=None, help="only the first N tasks")
    rep.add_argument("--budget", type=int, default=5000, help="continuous candidates per unsolved task")
    rep.add_argument("--jobs", type=int, default=max(1, (os.cpu_count() or 2) - 1))
    gen = sub.add_parser("generate", help="verify variants and write templates/variants.json")
    gen.add_argument("--templates", default="all", help="comma-separated ids, or all")
    gen.add_argument("--budget", type=int, default=3000, help="continuous candidates per sub-seed")
    gen.add_argument("--jobs", type=int, default=max(1, (os.cpu_count() or 2) - 1))
    args = parser.parse_args(argv)
    if args.command == "generate":
        from deepphy.envs.phyre.templates import templates

        ids = sorted(templates()) if args.templates == "all" else [int(t) for t in args.templates.split(",")]
        generate(ids, args.jobs, args.budget)
        return 0
    result = report(Path(args.out), args.jobs, args.splits, args.fold, args.budget, args.limit)
    s = result["summary"]
    print(f"{s['tasks']} tasks; solvable on the {s['grid']}: {s['solvable_on_grid']} "
          f"({100 * s['fraction_solvable_on_grid']:.1f}%); mean solving grid actions per task "
          f"{s['mean_solving_grid_actions']:.2f}; solvable in the continuous space: "
          f"{s['solvable_in_continuous_space']}/{s['tasks']}; {s['seconds']} s")
    for g, v in s["by_group"].items():
        print(f"  {g}: {v['tasks']} tasks, {100 * v['fraction_solvable_on_grid']:.1f}% solvable on the grid, "
              f"mean {v['mean_solving_grid_actions']:.2f} solving actions")
    if s["unsolved"]:
        print(f"  no solution found for: {', '.join(s['unsolved'][:20])}")
    print(f"wrote {args.out}")
    return 0 if not s["unsolved"] else 1


if __name__ == "__main__":
    sys.exit(main())
