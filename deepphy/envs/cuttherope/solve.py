"""Solvability of the Cut the Rope levels: replay the stored plans, search for plans, and
(re)make the level files.

    deepphy solve --env cuttherope report [--levels b1_l01,...] [--json FILE]
        Replay every level's stored plan through the environment (the plan's text, parsed
        and stepped as a model's replies are) and print the solvability report: per box,
        levels proven winnable, the stars of the stored plans, the best stars the search
        found, plan lengths, and how often the reference random agent wins. Seconds.

    deepphy solve --env cuttherope search [--levels ...] [--nodes N] [--jobs N] [--write]
        Run the oracle search (oracle.py) on the stored levels from scratch, with a budget
        of N simulated moves per level (machine-independent), report what it finds, and
        with --write store the best plan found where it has more stars than the stored one,
        or the stored one no longer wins (after a change of the rules). Minutes.

    deepphy solve --env cuttherope generate [--boxes 1,2] [--jobs N] [--nodes N]
        Remake the level files of the given boxes with the seeded procedures of design.py:
        propose layouts, keep those the oracle wins with the stage's mechanic, place three
        stars on the winning plan's path, order each stage from easy to hard. Overwrites
        levels/b<box>_l*.json. Tens of minutes.

`main(argv)` is the entry point (wired to `deepphy solve --env cuttherope ...`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from deepphy.envs.cuttherope import constants as C
from deepphy.envs.cuttherope.design import BOX_STAGES, place_stars, proposal, uses_mechanic
from deepphy.envs.cuttherope.level import BOXES, DesignInfo, Level, Solution, level_ids, load_level, save_level
from deepphy.envs.cuttherope.oracle import Plan, reference_win_rate, replay, search, trajectory
from deepphy.envs.cuttherope.sim import World, seconds_to_steps
from deepphy.seeding import seeded_rng

MAX_PROPOSALS = 60  # layouts tried per level before giving up
SEARCH_NODES = 2000  # oracle budget per level for `search`, in simulated moves
DESIGN_NODES = 1500  # oracle budget per proposal while designing, in simulated moves (machine-independent)
REFERENCE_EPISODES = 100  # episodes of the reference random agent per level


# -- design ----------------------------------------------------------------------------------------


def design_one(box: int, stage_index: int, seed: int, nodes: int = DESIGN_NODES) -> dict | None:
    """The first proposal of (box, stage, seed) that becomes a level (design.py's rules),
    as {"level": Level (id not yet final), "difficulty": ...}; None if none did."""
    stage = BOX_STAGES[box][stage_index]
    for attempt in range(MAX_PROPOSALS):
        rng = seeded_rng("cuttherope-design", box, stage.name, seed, attempt)
        try:
            level = proposal(box, stage, rng)
        except ValueError:  # pydantic's ValidationError included: an impossible layout
            continue
        idle = World.from_level(level)
        idle.run_on(seconds_to_steps(C.RUN_ON_CAP))
        if idle.status == "won":
            continue
        idle_loss = idle.reason if idle.status == "lost" else ""
        if stage.mechanic == "spider" and "spider" not in idle_loss:
            continue

        def accept(plan: Plan) -> bool:
            _, _, events = trajectory(level, plan.actions)
            return uses_mechanic(stage.mechanic, events, plan.texts, idle_loss)

        found = search(level, budget_s=math.inf, max_nodes=nodes, accept=accept)
        if found.best is None:
            continue
        plan = found.best
        _, path, _ = trajectory(level, plan.actions)
        stars = place_stars(rng, level, path)
        if stars is None:
            continue
        level = level.model_copy(update={"stars": stars})
        level = Level.model_validate(level.model_dump())
        check = replay(level, plan.texts)
        if not check["success"] or check["stars"] != 3:
            continue
        rate = reference_win_rate(level, seeded_rng("cuttherope-reference", box, stage.name, seed), REFERENCE_EPISODES)
        if rate < stage.min_reference_rate:
            continue
        level = level.model_copy(update={
            "solution": Solution(actions=plan.texts, stars=3, best_stars=3),
            "design": DesignInfo(stage=stage.name, seed=seed, reference_win_rate=rate),
        })
        return {"level": level, "difficulty": (-rate, len(plan.texts), attempt)}
    return None


def _design_job(args: tuple[int, int, int, int]) -> tuple[int, int, int, dict | None]:
    box, stage_index, seed, nodes = args
    return box, stage_index, seed, design_one(box, stage_index, seed, nodes)


def generate(boxes: list[int], jobs: int, nodes: int) -> int:
    work = [(box, s, seed, nodes) for box in boxes for s, stage in enumerate(BOX_STAGES[box])
            for seed in range(stage.count)]
    results: dict[tuple[int, int], list[dict]] = {}
    start = time.perf_counter()
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        for n, (box, s, seed, made) in enumerate(pool.map(_design_job, work), 1):
            stage = BOX_STAGES[box][s]
            if made is None:
                print(f"box {box} stage {stage.name!r} seed {seed}: no level found", file=sys.stderr)
                return 1
            results.setdefault((box, s), []).append(made)
            print(f"[{n}/{len(work)} {time.perf_counter() - start:.0f}s] box {box} {stage.name!r} seed {seed}: "
                  f"{made['level'].solution.actions} reference win rate {made['level'].design.reference_win_rate:.2f}",
                  file=sys.stderr)
    for box in boxes:
        number = 0
        for s in range(len(BOX_STAGES[box])):
            for made in sorted(results[(box, s)], key=lambda m: m["difficulty"]):
                number += 1
                level = made["level"].model_copy(update={"id": f"b{box}_l{number:02d}"})
                save_level(Level.model_validate(level.model_dump()))
        assert number == BOXES[box], (box, number)
    return 0


# -- report ----------------------------------------------------------------------------------------


def report(ids: list[str]) -> dict:
    rows = []
    for level_id in ids:
        level = load_level(level_id)
        sol = level.solution
        check = replay(level, sol.actions) if sol else {"success": False, "stars": 0, "actions": 0, "outcome": "no plan"}
        rows.append({
            "level": level_id, "box": level.box, "proven": bool(check["success"]), "plan_stars": check["stars"] or 0,
            "stored_stars": sol.stars if sol else None, "best_stars": sol.best_stars if sol else None,
            "actions": len(sol.actions) if sol else None, "outcome": check["outcome"],
            "reference_win_rate": level.design.reference_win_rate if level.design else None,
        })
    boxes = {}
    for box in sorted({r["box"] for r in rows}):
        rs = [r for r in rows if r["box"] == box]
        rates = [r["reference_win_rate"] for r in rs if r["reference_win_rate"] is not None]
        boxes[box] = {
            "levels": len(rs), "proven": sum(r["proven"] for r in rs),
            "plan_stars": sum(r["plan_stars"] for r in rs), "best_stars": sum(r["best_stars"] or 0 for r in rs),
            "three_star_levels": sum((r["best_stars"] or 0) == 3 for r in rs),
            "mean_actions": sum(r["actions"] or 0 for r in rs) / len(rs),
            "reference_win_rate": sum(rates) / len(rates) if rates else None,
        }
    return {"levels": rows, "boxes": boxes}


def print_report(data: dict) -> None:
    print(f"{'box':>4} {'levels':>6} {'proven':>6} {'plan stars':>10} {'best stars':>10} {'3-star':>6} "
          f"{'actions':>7} {'random wins':>11}")
    total = {"levels": 0, "proven": 0, "plan_stars": 0, "best_stars": 0, "three_star_levels": 0}
    for box, b in data["boxes"].items():
        rate = "-" if b["reference_win_rate"] is None else f"{100 * b['reference_win_rate']:.1f}%"
        print(f"{box:>4} {b['levels']:>6} {b['proven']:>6} {b['plan_stars']:>10} {b['best_stars']:>10} "
              f"{b['three_star_levels']:>6} {b['mean_actions']:>7.1f} {rate:>11}")
        for k in total:
            total[k] += b[k]
    print(f"{'all':>4} {total['levels']:>6} {total['proven']:>6} {total['plan_stars']:>10} {total['best_stars']:>10} "
          f"{total['three_star_levels']:>6}")
    failed = [r for r in data["levels"] if not r["proven"]]
    for r in failed:
        print(f"NOT PROVEN: {r['level']}: {r['outcome']}")


# -- search ----------------------------------------------------------------------------------------


def _search_job(args: tuple[str, int]) -> dict:
    level_id, nodes = args
    level = load_level(level_id)
    found = search(level, budget_s=math.inf, max_nodes=nodes)
    best = found.best
    return {"level": level_id, "found": best is not None, "stars": best.stars if best else None,
            "plan": best.texts if best else None, "nodes": found.nodes, "seconds": round(found.seconds, 1)}


def _still_wins(level: Level, plan: Solution) -> bool:
    """The stored plan still wins with its stars, using all its actions."""
    out = replay(level, plan.actions)
    return out["success"] and out["stars"] == plan.stars and out["actions"] == len(plan.actions)


def run_search(ids: list[str], nodes: int, jobs: int, write: bool) -> int:
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        results = list(pool.map(_search_job, [(i, nodes) for i in ids]))
    for r in results:
        print(f"{r['level']}: " + (f"{r['stars']} star(s) in {len(r['plan'])} actions {r['plan']}" if r["found"]
                                   else "no plan found") + f"  ({r['nodes']} moves, {r['seconds']} s)")
        if write and r["found"]:
            level = load_level(r["level"])
            stored = level.solution
            stale = stored is None or not _still_wins(level, stored)
            if stale or r["stars"] > stored.stars:
                check = replay(level, r["plan"])
                if check["success"]:
                    save_level(level.model_copy(update={"solution": Solution(
                        actions=r["plan"], stars=check["stars"], best_stars=check["stars"])}))
            elif r["stars"] > stored.best_stars:
                save_level(level.model_copy(update={"solution": stored.model_copy(update={"best_stars": r["stars"]})}))
    for box in sorted({r["level"][:2] for r in results}):
        rs = [r for r in results if r["level"].startswith(box)]
        found = [r for r in rs if r["found"]]
        print(f"box {box[1]}: plans for {len(found)} of {len(rs)} levels, {sum(r['stars'] for r in found)} stars, "
              f"{sum(r['stars'] == 3 for r in found)} with 3 stars")
    print(f"found plans for {sum(r['found'] for r in results)} of {len(results)} levels")
    return 0


# -- command line ----------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="deepphy solve --env cuttherope", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    rep = sub.add_parser("report", help="replay every stored plan; print the solvability report")
    rep.add_argument("--levels", help="comma-separated level ids (default: all 88)")
    rep.add_argument("--json", help="also write the report as JSON to this file")
    sea = sub.add_parser("search", help="run the oracle search on the stored levels")
    sea.add_argument("--levels")
    sea.add_argument("--nodes", type=int, default=SEARCH_NODES, help="search budget per level (simulated moves)")
    sea.add_argument("--jobs", type=int, default=1)
    sea.add_argument("--write", action="store_true", help="store plans with more stars than the stored ones")
    gen = sub.add_parser("generate", help="remake the level files of some boxes (design.py)")
    gen.add_argument("--boxes", default="1,2,3,4,5")
    gen.add_argument("--jobs", type=int, default=1)
    gen.add_argument("--nodes", type=int, default=DESIGN_NODES, help="search budget per proposal (simulated moves)")
    args = parser.parse_args(argv)

    ids = level_ids()
    if getattr(args, "levels", None):
        wanted = [s.strip() for s in args.levels.split(",") if s.strip()]
        unknown = [i for i in wanted if i not in ids]
        if unknown:
            parser.error(f"unknown level(s): {', '.join(unknown)}")
        ids = wanted
    if args.command == "report":
        data = report(ids)
        print_report(data)
        if args.json:
            Path(args.json).write_text(json.dumps(data, indent=1) + "\n")
        return 0 if all(r["proven"] for r in data["levels"]) else 1
    if args.command == "search":
        return run_search(ids, args.nodes, args.jobs, args.write)
    boxes = [int(b) for b in args.boxes.split(",")]
    if any(b not in BOXES for b in boxes):
        parser.error(f"boxes are {', '.join(map(str, BOXES))}")
    return generate(boxes, args.jobs, args.nodes)


if __name__ == "__main__":
    sys.exit(main())
