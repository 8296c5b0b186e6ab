"""The Angry Birds oracle: prove every level winnable with its birds and find its best score.

    deepphy solve --env angrybirds report [--levels s1_l01,...] [--json FILE]
        Replay every level's stored winning plan and print the solvability report (per
        level: birds, pigs, shots the plan needs, its score, the star thresholds, the
        stars the replay earns). Fails (exit 1) if a stored plan no longer wins with its
        stored score. Takes seconds.

    deepphy solve --env angrybirds search [--levels ...] [--jobs 2] [--dry-run]
        Search each level again and store the best winning plan found, its score and the
        star thresholds derived from it in the level file (levels.star_thresholds).

The search, per level (deterministic: fixed grids, ties broken by grid order):
- Beam search over shot sequences, one bird per depth. At each depth every state of the
  beam is extended by every shot of a coarse grid (GRID_ANGLES x GRID_POWERS); then the
  best extensions are refined by local steps in angle and power (REFINE_STEPS), a step
  kept when it improves the outcome. A state is a plan; it is simulated by rebuilding
  the level and replaying the plan (pymunk spaces are never copied).
- Outcomes are ranked by (won, score, pigs killed, -pig hit points left, blocks destroyed).
- The first depth at which any plan wins ends the search: a win with fewer birds beats any
  win with more (SCORE_UNUSED_BIRD outweighs what extra destruction can earn); the winners
  of that depth are refined for score. Otherwise the best BEAM distinct states (by which
  pigs are left) go on to the next depth.

`main(argv)` is the entry point (wired to `deepphy solve --env angrybirds`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from deepphy.envs.angrybirds import constants as C
from deepphy.envs.angrybirds.levels import Level, Oracle, Shot, level_ids, load_level, save_level, star_thresholds
from deepphy.envs.angrybirds.sim import World

GRID_ANGLES = tuple(float(a) for a in range(0, 86, 5))  # 18 angles
GRID_POWERS = (0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)  # 7 powers
BEAM = 4  # states kept per depth
REFINE_TOP = 6  # extensions refined per depth
REFINE_STEPS = ((2.5, 0.05), (1.0, 0.02), (0.4, 0.01))  # (degrees, power) per refinement round


@dataclass(frozen=True)
class Outcome:
    plan: tuple[tuple[float, float], ...]
    won: bool
    score: int
    pigs_killed: int
    blocks: int
    pig_hp: float  # hit-point fraction the surviving pigs have left, summed
    alive: tuple[int, ...]  # which pigs survive (to keep the beam diverse)

    @property
    def rank(self) -> tuple:
        return (self.won, self.score, self.pigs_killed, -self.pig_hp, self.blocks)


def simulate(level: Level, plan) -> Outcome:
    """Replay `plan` ((angle, power) per bird, in order) on a freshly built level."""
    world = World(level)
    shots = 0
    for angle, power in plan:
        world.shoot(level.birds[shots], angle, power)
        shots += 1
        if world.pigs_left == 0:
            break
    pigs = world.alive("pig")
    return Outcome(
        plan=tuple(plan[:shots]),
        won=not pigs,
        score=world.score(shots),
        pigs_killed=world.pigs_killed,
        blocks=world.blocks_destroyed,
        pig_hp=sum(p.hp / p.max_hp for p in pigs),
        alive=tuple(p.index for p in pigs),
    )


def _clip(angle: float, power: float) -> tuple[float, float]:
    return (round(min(max(angle, C.ANGLE_MIN), C.ANGLE_MAX), 2),
            round(min(max(power, 0.05), C.POWER_MAX), 2))


class Search:
    def __init__(self, level: Level) -> None:
        self.level = level
        self.sims = 0
        self._seen: dict[tuple, Outcome] = {}

    def run(self, plan) -> Outcome:
        key = tuple(plan)
        if key not in self._seen:
            self._seen[key] = simulate(self.level, list(plan))
            self.sims += 1
        return self._seen[key]

    def refine(self, start: Outcome) -> Outcome:
        """Local steps on the last shot of `start`'s plan, kept while they improve it."""
        best = start
        prefix = best.plan[:-1]
        for da, dp in REFINE_STEPS:
            improved = True
            while improved:
                improved = False
                a, p = best.plan[-1]
                for sa, sp in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)):
                    cand = self.run(prefix + (_clip(a + sa * da, p + sp * dp),))
                    if cand.rank > best.rank and len(cand.plan) == len(best.plan):
                        best, improved = cand, True
        return best

    def solve(self) -> Outcome | None:
        frontier: list[Outcome] = [simulate(self.level, [])]
        grid = [(a, p) for a in GRID_ANGLES for p in GRID_POWERS]
        for depth in range(1, len(self.level.birds) + 1):
            children = [self.run(node.plan + (shot,)) for node in frontier for shot in grid]
            children.sort(key=lambda o: o.rank, reverse=True)  # stable: grid order breaks ties
            refined = [self.refine(c) for c in _distinct(children, REFINE_TOP)]
            pool = sorted(refined + children, key=lambda o: o.rank, reverse=True)
            if pool[0].won:
                return pool[0]
            frontier = _distinct(pool, BEAM)
        return None


def _distinct(outcomes: list[Outcome], n: int) -> list[Outcome]:
    """The first `n` outcomes that leave different sets of pigs (or differ in blocks broken)."""
    out, seen = [], set()
    for o in outcomes:
        key = (o.alive, o.blocks)
        if key not in seen:
            seen.add(key)
            out.append(o)
            if len(out) == n:
                break
    return out


def search_level(level_id: str) -> tuple[str, Outcome | None, int, float]:
    t0 = time.process_time()
    search = Search(load_level(level_id))
    best = search.solve()
    return level_id, best, search.sims, time.process_time() - t0


def store(level: Level, best: Outcome, sims: int) -> Level:
    oracle = Oracle(plan=[Shot(angle=a, power=p) for a, p in best.plan], score=best.score,
                    blocks_destroyed=best.blocks, searched=sims)
    updated = level.model_copy(update={"oracle": oracle, "stars": star_thresholds(level, best.score)})
    Level.model_validate(updated.model_dump())  # still a valid level
    save_level(updated)
    return updated


# -- the report -----------------------------------------------------------------------------


def report_rows(ids: list[str]) -> list[dict]:
    rows = []
    for level_id in ids:
        level = load_level(level_id)
        row = {"level": level_id, "title": level.title, "birds": "".join(_letter(b) for b in level.birds),
               "pigs": len(level.pigs), "blocks": len(level.blocks), "tnt": len(level.tnt)}
        if level.oracle is None or level.stars is None:
            rows.append({**row, "winnable": False, "problem": "no stored plan"})
            continue
        replay = simulate(level, [(s.angle, s.power) for s in level.oracle.plan])
        stars = level.stars.of(replay.won, replay.score)
        problem = None
        if not replay.won:
            problem = "the stored plan no longer wins"
        elif replay.score != level.oracle.score:
            problem = f"the stored plan scores {replay.score}, not {level.oracle.score}"
        rows.append({**row, "winnable": replay.won, "shots": len(replay.plan),
                     "plan": [f"({a:g}, {p:g})" for a, p in replay.plan], "best_score": replay.score,
                     "least_win": level.least_win_score, "two_stars": level.stars.two,
                     "three_stars": level.stars.three, "stars": stars, "blocks_destroyed": replay.blocks,
                     "searched": level.oracle.searched, "problem": problem})
    return rows


def _letter(bird: str) -> str:
    return next(k for k, v in C.BIRD_LETTERS.items() if v == bird)


def print_report(rows: list[dict]) -> None:
    print(f"{'level':7} {'birds':9} {'pigs':>4} {'blk':>4} {'tnt':>3} {'shots':>5} {'best':>6} "
          f"{'2*':>6} {'3*':>6} {'stars':>5}  plan")
    for r in rows:
        if "shots" not in r:
            print(f"{r['level']:7} {r['birds']:9} {r['pigs']:4d} {r['blocks']:4d} {r['tnt']:3d}  {r['problem']}")
            continue
        note = f"  PROBLEM: {r['problem']}" if r["problem"] else ""
        print(f"{r['level']:7} {r['birds']:9} {r['pigs']:4d} {r['blocks']:4d} {r['tnt']:3d} {r['shots']:5d} "
              f"{r['best_score']:6d} {r['two_stars']:6d} {r['three_stars']:6d} {r['stars']:5d}  "
              f"{' '.join(r['plan'])}{note}")
    ok = sum(1 for r in rows if r.get("winnable") and not r.get("problem"))
    print(f"{ok}/{len(rows)} levels proven winnable by their stored plan")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="deepphy solve --env angrybirds", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    rep = sub.add_parser("report", help="replay the stored plans; print the solvability report")
    rep.add_argument("--levels", help="comma-separated level ids (default: all)")
    rep.add_argument("--json", help="also write the report as JSON to this file")
    srch = sub.add_parser("search", help="search the levels again; store plans and star thresholds")
    srch.add_argument("--levels", help="comma-separated level ids (default: all)")
    srch.add_argument("--jobs", type=int, default=2, help="processes (default 2)")
    srch.add_argument("--dry-run", action="store_true", help="print what was found, write nothing")
    args = parser.parse_args(argv)

    ids = level_ids()
    if args.levels:
        wanted = [x.strip() for x in args.levels.split(",") if x.strip()]
        unknown = [x for x in wanted if x not in ids]
        if unknown:
            parser.error(f"unknown levels: {', '.join(unknown)}")
        ids = wanted

    if args.command == "search":
        failed = []
        with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            for level_id, best, sims, cpu in pool.map(search_level, ids):
                if best is None:
                    failed.append(level_id)
                    print(f"{level_id}: NO WIN FOUND ({sims} shots simulated, {cpu:.0f} s)", flush=True)
                    continue
                print(f"{level_id}: wins in {len(best.plan)} shot(s), score {best.score}, "
                      f"{best.blocks} blocks ({sims} plans simulated, {cpu:.0f} s CPU)", flush=True)
                if not args.dry_run:
                    store(load_level(level_id), best, sims)
        if args.dry_run:
            return 1 if failed else 0
        rows = report_rows(ids)
        print_report(rows)
        return 1 if failed or any(r.get("problem") for r in rows) else 0

    rows = report_rows(ids)
    print_report(rows)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")
    return 0 if all(r.get("winnable") and not r.get("problem") for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
