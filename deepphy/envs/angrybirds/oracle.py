"""The Angry Birds oracle: the fewest birds a level needs, a robust winning plan, and the
measurements that calibrate a level (the random baseline, robustness, stars).

Search, per level (deterministic: fixed grids, ties broken by grid order):
- Depth 1 tries every shot of FINE_GRID (1 degree x 0.05 power, powers 0.3 to 1). A level
  "needs 2+ birds" when none of them wins: that is the stated evidence for the minimum
  (a one-shot win narrower than the grid would be a knife-edge no plan should rely on).
- Deeper, the search keeps set-up shots: the depth's outcomes are grouped by what they
  leave (which pigs live, which blocks are broken or moved); each group is represented by its
  centre, the shot with the most grid neighbours in the same group, and the SETUPS groups
  that did most (pigs killed, pig hit points taken, blocks broken) are extended by every
  shot of COARSE_GRID (2 degrees x 0.05); a set-up may break blocks, hurt pigs or just
  knock blocks out of place (a lid pushed off a well). The first depth at which a plan wins ends the
  search. Minimum birds above 2 are "none found by this search", not a proof.
- At the winning depth every winning shot is ranked by its winning grid neighbours (the
  centre of a winning region beats a knife-edge); the CANDIDATES best are measured for
  robustness, the CENTRED most robust of them are centred (`centre`: each shot in turn
  moves, within +-3 degrees and +-0.06 power, to the point of a 0.5 degree x 0.01 grid
  whose nudges win most often), and the stored plan is the highest-scoring one that is
  ROBUST_ENOUGH (else the most robust).

Robustness of a plan (`robustness`): for each of its shots in turn, the 25 plans that move
that shot by -1, -0.5, 0, 0.5, 1 degree and -0.02, -0.01, 0, 0.01, 0.02 power (every other
shot as stored, not re-aimed) and the share of them that still win; the plan's robustness
is the smallest share over its shots (its weakest shot).

The reference random baseline (`reference_episode`) draws exactly what `deepphy run
--model mock` draws: the generator seeded by ("mock", seed, "angrybirds", level, run,
attempt 1, step), through ShootSpace.reference_reply and the parser.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from deepphy.envs.angrybirds import constants as C
from deepphy.envs.angrybirds.levels import Level
from deepphy.envs.angrybirds.sim import World
from deepphy.envs.angrybirds.space import ShootSpace
from deepphy.seeding import seeded_rng

POWERS = tuple(round(0.3 + 0.05 * k, 2) for k in range(15))  # 0.3 .. 1.0
FINE_GRID = tuple((float(a), p) for a in range(0, 91) for p in POWERS)  # 1365 shots
COARSE_GRID = tuple((float(a), p) for a in range(0, 91, 2) for p in POWERS)  # 690 shots
QUICK_GRID = tuple((float(a), p) for a in range(0, 91, 4) for p in POWERS[::2])  # 184 shots: the ability check
SETUPS = 4  # set-up states extended per depth
CANDIDATES = 6  # winning plans measured for robustness
CENTRED = 2  # of those, the most robust are centred
ROBUST_ENOUGH = 0.6  # a plan this robust may be chosen for its score
MOVED = 0.3  # u: a block displaced this far (or turned 20 degrees) was knocked out of place
NUDGES = tuple((da, dp) for da in (-1.0, -0.5, 0.0, 0.5, 1.0) for dp in (-0.02, -0.01, 0.0, 0.01, 0.02))
REFERENCE = "mock"  # the baseline whose draws the calibration reproduces


@dataclass(frozen=True)
class Outcome:
    plan: tuple[tuple[float, float], ...]  # the shots taken (a win ends the plan early)
    won: bool
    score: int
    pigs_killed: int
    blocks: int
    pig_hp: float  # hit-point fraction the surviving pigs have left, summed
    alive: tuple[int, ...]  # which pigs survive
    broken: tuple[int, ...]  # which blocks and crates are gone
    moved: tuple[int, ...]  # which surviving blocks and crates were knocked out of place
    abilities: int = 0  # shots whose bird used its ability (dashed, split or exploded)

    @property
    def progress(self) -> tuple:
        return (self.won, self.pigs_killed, -round(self.pig_hp, 3), self.blocks, len(self.moved))

    @property
    def what(self) -> tuple:
        return (self.alive, self.broken, self.moved)


def simulate(level: Level, plan, abilities: bool = True) -> Outcome:
    """Replay `plan` ((angle, power) per bird, in order) on a freshly built level
    (`abilities=False`: the birds without their abilities)."""
    world = World(level, abilities=abilities)
    start = {t.index: (t.body.position, t.body.angle) for t in world.things}
    shots = used = 0
    for angle, power in plan:
        used += world.shoot(level.birds[shots], angle, power).ability_acted
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
        broken=tuple(t.index for t in world.things if not t.alive and t.kind in ("block", "tnt")),
        moved=tuple(t.index for t in world.things if t.alive and t.kind in ("block", "tnt")
                    and (abs(t.body.position - start[t.index][0]) > MOVED
                         or abs(t.body.angle - start[t.index][1]) > math.radians(20))),
        abilities=used,
    )


def _clip(angle: float, power: float) -> tuple[float, float]:
    return (round(min(max(angle, C.ANGLE_MIN), C.ANGLE_MAX), 2),
            round(min(max(power, C.POWER_MIN), C.POWER_MAX), 2))


def robustness(level: Level, plan, cache: dict | None = None) -> float:
    """The share of nudged plans that still win, for the plan's weakest shot (module doc)."""
    cache = {} if cache is None else cache
    shares = []
    for j in range(len(plan)):
        wins = 0
        for da, dp in NUDGES:
            nudged = tuple(plan[:j]) + (_clip(plan[j][0] + da, plan[j][1] + dp),) + tuple(plan[j + 1:])
            if nudged not in cache:
                cache[nudged] = simulate(level, nudged)
            wins += cache[nudged].won
        shares.append(wins / len(NUDGES))
    return min(shares)


def centre(level: Level, plan: tuple, cache: dict) -> tuple:
    """Move each shot of a winning plan, in turn, to the centre of its winning region (module
    doc); the rest of the plan stays as it is."""
    plan = tuple(plan)
    steps_a = [0.5 * k for k in range(-6, 7)]
    steps_p = [0.01 * k for k in range(-6, 7)]
    for j in range(len(plan)):
        a0, p0 = plan[j]
        won = {}
        for i, da in enumerate(steps_a):
            for k, dp in enumerate(steps_p):
                shot = _clip(a0 + da, p0 + dp)
                trial = plan[:j] + (shot,) + plan[j + 1:]
                if trial not in cache:
                    cache[trial] = simulate(level, trial)
                won[(i, k)] = (shot, cache[trial].won)
        best = None
        for (i, k), (shot, ok) in won.items():
            if not ok:
                continue
            support = sum(won.get((i + di, k + dk), (None, False))[1] for di in (-2, -1, 0, 1, 2) for dk in (-2, -1, 0, 1, 2))
            key = (support, -abs(i - 6) - abs(k - 6))
            if best is None or key > best[0]:
                best = (key, shot)
        if best is not None:
            plan = plan[:j] + (best[1],) + plan[j + 1:]
    return plan


def _neighbours(grid: tuple) -> dict[tuple[float, float], list[tuple[float, float]]]:
    """The 8 grid neighbours of each grid shot."""
    angles = sorted({a for a, _ in grid})
    powers = sorted({p for _, p in grid})
    ai = {a: i for i, a in enumerate(angles)}
    pi = {p: i for i, p in enumerate(powers)}
    out = {}
    for a, p in grid:
        out[(a, p)] = [(angles[ai[a] + i], powers[pi[p] + j]) for i in (-1, 0, 1) for j in (-1, 0, 1)
                       if (i or j) and 0 <= ai[a] + i < len(angles) and 0 <= pi[p] + j < len(powers)]
    return out


@dataclass
class SearchResult:
    best: Outcome | None
    robustness: float = 0.0
    searched: int = 0  # plans simulated
    shorter_tried: int = 0  # plans with fewer shots than the winner's, none winning
    depth_wins: dict[int, int] = field(default_factory=dict)  # winning grid shots at the winning depth
    fine_one_shot: tuple[int, int] = (0, 0)  # (wins, shots) of depth 1 with power >= 0.5 (the reference range)


class Search:
    def __init__(self, level: Level, log=None, abilities: bool = True) -> None:
        self.level = level
        self.log = log or (lambda text: None)
        self.abilities = abilities
        self._seen: dict[tuple, Outcome] = {}

    def run(self, plan: tuple) -> Outcome:
        if plan not in self._seen:
            self._seen[plan] = simulate(self.level, plan, self.abilities)
        return self._seen[plan]

    def first_win(self, max_depth: int) -> Outcome | None:
        """The first win the search meets within `max_depth` birds (QUICK_GRID at every
        depth, extending the single most productive set-up, chosen as in `solve`), or None:
        a quick, greedy test of winnability."""
        frontier: list[tuple] = [()]
        near = _neighbours(QUICK_GRID)
        for _ in range(min(max_depth, len(self.level.birds))):
            layers = []
            for prefix in frontier:
                outs = {}
                for shot in QUICK_GRID:
                    outs[shot] = o = self.run(prefix + (shot,))
                    if o.won:
                        return o
                layers.append((prefix, outs))
            frontier = self._setups(layers, near)[:1]
        return None

    def _depth(self, prefix: tuple, grid: tuple) -> dict[tuple[float, float], Outcome]:
        return {shot: self.run(prefix + (shot,)) for shot in grid}

    def solve(self, fine: bool = True, max_depth: int | None = None) -> SearchResult:
        """`fine`: depth 1 on FINE_GRID (the evidence for "needs 2+ birds"); else COARSE_GRID."""
        level = self.level
        result = SearchResult(best=None)
        frontier: list[tuple] = [()]
        shorter = 0
        for depth in range(1, min(max_depth or len(level.birds), len(level.birds)) + 1):
            grid = FINE_GRID if depth == 1 and fine else COARSE_GRID
            near = _neighbours(grid)
            layers = []
            for prefix in frontier:
                layers.append((prefix, self._depth(prefix, grid)))
            if depth == 1:
                first = layers[0][1]
                ref = [o for (a, p), o in first.items() if p >= 0.5]
                result.fine_one_shot = (sum(o.won for o in ref), len(ref))
            wins = [(prefix, shot, o) for prefix, outs in layers for shot, o in outs.items() if o.won]
            self.log(f"depth {depth}: {len(frontier)} prefix(es) x {len(grid)} shots, {len(wins)} win(s), "
                     f"{len(self._seen)} plans simulated")
            if wins:
                result.best, result.robustness = self._choose(layers, near)
                result.depth_wins = {depth: len(wins)}
                break
            shorter += sum(len(outs) for _, outs in layers)
            frontier = self._setups(layers, near)
        result.searched = len(self._seen)
        result.shorter_tried = shorter
        return result

    def _setups(self, layers, near) -> list[tuple]:
        """The centres of the SETUPS most productive outcome groups of this depth."""
        groups: dict[tuple, list] = {}
        for prefix, outs in layers:
            for shot, o in outs.items():
                groups.setdefault((prefix, o.what), []).append((shot, o))
        best = []
        for (prefix, what), members in groups.items():
            outs = dict(members)
            centre, o = max(members, key=lambda m: (sum(n in outs for n in near[m[0]]), m[1].score))
            support = sum(n in outs for n in near[centre])
            best.append(((o.progress, support), prefix + (centre,)))
        best.sort(key=lambda b: b[0], reverse=True)
        return [plan for _, plan in best[:SETUPS]]

    def _choose(self, layers, near) -> tuple[Outcome, float]:
        ranked = []
        for prefix, outs in layers:
            for shot, o in outs.items():
                if o.won:
                    support = sum(outs[n].won for n in near[shot])
                    ranked.append((support, o.score, prefix + (shot,)))
        ranked.sort(key=lambda r: (r[0], r[1]), reverse=True)
        measured = []
        for support, score, plan in ranked[:CANDIDATES]:
            o = self.run(plan)
            r = robustness(self.level, plan, self._seen)
            measured.append((r, o))
            self.log(f"  candidate {_fmt(plan)}: {support} winning neighbours, robustness {r:.2f}, score {o.score}")
        measured.sort(key=lambda m: (m[0], m[1].score), reverse=True)
        for r, o in list(measured[:CENTRED]):
            plan = centre(self.level, o.plan, self._seen)
            if plan != o.plan:
                o, r = self.run(plan), robustness(self.level, plan, self._seen)
                measured.append((r, o))
                self.log(f"  centred {_fmt(plan)}: robustness {r:.2f}, score {o.score}")
        measured.sort(key=lambda m: (m[0] >= ROBUST_ENOUGH, m[1].score if m[0] >= ROBUST_ENOUGH else 0, m[0]),
                      reverse=True)
        r, o = measured[0]
        return o, r


def ability_needed(level: Level, plan) -> str:
    """Whether the abilities of the level's birds matter to a winning plan: "-" when the
    level has only red birds; "unused" when no bird of `plan` (a winning plan) uses its
    ability; "no" when the birds win without abilities with as few birds as `plan` (the
    plan itself, or the first win the greedy `Search.first_win` meets on its 4 degree x 0.1
    grid); "yes" when that search finds no such win (evidence from a quick search, not a
    proof)."""
    if set(level.birds) == {"red"}:
        return "-"
    if not simulate(level, plan).abilities:
        return "unused"
    if simulate(level, plan, abilities=False).won:
        return "no"
    return "no" if Search(level, abilities=False).first_win(len(plan)) else "yes"


def _fmt(plan) -> str:
    return " ".join(f"({a:g}, {p:g})" for a, p in plan)


# -- the reference random baseline --------------------------------------------------------------


@dataclass(frozen=True)
class Episode:
    won: bool
    shots: int  # birds launched
    score: int
    stars: int
    capped: int  # shots that stopped at SHOT_MAX_TIME


def reference_episode(level: Level, seed: int, run: int) -> Episode:
    """One episode of the reference random baseline, drawn as `deepphy run --model mock`
    draws it (run `run` of a run with seed `seed`; one attempt)."""
    space = ShootSpace()
    world = World(level)
    shots = capped = 0
    for step in range(1, len(level.birds) + 1):
        rng = seeded_rng(REFERENCE, seed, "angrybirds", level.id, run, 1, step)
        action = space.parse(space.reference_reply(rng))
        shot = world.shoot(level.birds[step - 1], action.angle, action.power)
        shots += 1
        capped += not shot.at_rest
        if world.pigs_left == 0:
            break
    won = world.pigs_left == 0
    score = world.score(shots)
    stars = level.stars.of(won, score) if level.stars else int(won)
    return Episode(won=won, shots=shots, score=score, stars=stars, capped=capped)
