"""The oracle: a beam search over action sequences that finds winning plans, and the
measurements of a level built on it (calibrate.py reports them).

A plan is a list of actions in the game's own vocabulary. The search builds it one
"move" at a time: optionally a sleep (a grid of durations, `SEARCH_SLEEPS`), then one
element action (cut a pin or two at once, cut an active pin, pop a bubble, tap a cushion
1/3/5 times). Every move is simulated from a snapshot of the world (`World.snapshot`,
exact: the world rebuilds its pymunk space from its own state at every decision) by the
environment's own rules (`env.act`). After each move a rollout lets the world run on
without actions: if the candy reaches Om Nom the plan (+ `success()` when the win comes
after the last action) is a solution. The best `beam` moves by a guide score (stars
touched, closest approach to Om Nom, halves' gap) go on to the next layer. The search
stops at its budget of simulated moves (machine-independent), after a 3-star plan, or
when no plan can grow within the decision limit.

Results are verified by replaying the plan's text through the environment itself
(`replay`), so the stored plans are what a model's identical actions would do.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from deepphy.envs.cuttherope import constants as C
from deepphy.envs.cuttherope.env import Attempt, act
from deepphy.envs.cuttherope.level import Level
from deepphy.envs.cuttherope.sim import World, seconds_to_steps
from deepphy.envs.cuttherope.space import CutAction, CutSpace, format_seconds

SEARCH_SLEEPS = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0)  # sleep before a move (0: none)
ROLLOUT = 6.0  # s the world runs on after a move to see where it leads (<= RUN_ON_CAP)
SEARCH_NODES = 1500  # default budget of a search, in simulated moves
BEAM = 10  # moves kept per layer
SUCCESS = CutAction(name="success")
ANY = CutSpace(num_pins=9, num_active_pins=9, num_bubbles=9, num_cushions=9, pins=list(range(1, 10)),
               active_pins=list(range(1, 10)), bubbles=list(range(1, 10)))  # parses any plan's text


def moves(world: World) -> list[CutAction]:
    """Every element action now: each rope cut alone or with another, bubbles, cushion taps."""
    avail = world.available()
    return CutSpace(num_pins=len(world.level.pins), num_active_pins=len(world.level.active_pins),
                    num_cushions=len(avail["cushions"]), pins=avail["pins"], active_pins=avail["active_pins"],
                    bubbles=avail["bubbles"]).element_actions()


def texts_of(actions: list[CutAction]) -> list[str]:
    return [ANY.format(a) for a in actions]


@dataclass
class Plan:
    actions: list[CutAction]
    stars: int

    @property
    def texts(self) -> list[str]:
        return texts_of(self.actions)


@dataclass
class SearchResult:
    best: Plan | None = None
    solutions: int = 0
    nodes: int = 0
    plans: list[Plan] = field(default_factory=list)  # every distinct solution found (best first)


@dataclass
class _Node:
    world: World
    actions: list[CutAction]
    score: float = 0.0


def _guide(world: World, rollout: World, n_actions: int) -> float:
    """Higher is better: stars touched, closeness to Om Nom, halves coming together."""
    score = 60.0 * rollout.stars_collected - min(world.min_mouth_distance, rollout.min_mouth_distance, 1000.0)
    if world.level.halves and not any(c.alive and not c.half for c in rollout.candies) and rollout.status != "won":
        score -= 400.0 + min(world.min_join_gap, rollout.min_join_gap, 1000.0)
    if rollout.status == "lost":
        score -= 150.0
    return score - 3.0 * n_actions


def search(level: Level, *, max_nodes: int = SEARCH_NODES, beam: int = BEAM, want_stars: int = 3,
           max_actions: int = C.MAX_ACTIONS, sleeps: tuple[float, ...] = SEARCH_SLEEPS,
           accept: Callable[[Plan], bool] | None = None,
           forbid: Callable[[CutAction], bool] | None = None) -> SearchResult:
    """Beam search for winning plans of at most `max_actions` actions within `max_nodes`
    simulated moves. Stops at a plan with `want_stars` stars; with `accept`, keeps only the
    solutions it accepts and stops at the first; `forbid` leaves out the moves it names."""
    result = SearchResult()
    found: dict[tuple[str, ...], Plan] = {}
    rollout_steps = seconds_to_steps(ROLLOUT)

    def record(actions: list[CutAction], stars: int) -> None:
        plan = Plan(list(actions), stars)
        key = tuple(plan.texts)
        if key not in found and (accept is None or accept(plan)):
            found[key] = plan
            result.solutions += 1

    def done() -> bool:
        best = max((p.stars for p in found.values()), default=-1)
        return best >= want_stars or (accept is not None and bool(found)) or result.nodes >= max_nodes

    layer = [_Node(World.from_level(level), [])]
    while layer and not done():
        children: list[_Node] = []
        for node in layer:
            for pause in sleeps:
                base, prefix = node.world, list(node.actions)
                if pause > 0:
                    if len(prefix) + 2 > max_actions:
                        continue
                    base = base.snapshot()
                    nap = CutAction(name="sleep", seconds=pause)
                    act(base, nap)
                    prefix.append(nap)
                    result.nodes += 1
                    if base.status == "won":
                        record(prefix, base.stars_collected)
                        continue
                    if base.decided:
                        continue
                if len(prefix) + 1 > max_actions:
                    continue
                for move in moves(base):
                    if forbid is not None and forbid(move):
                        continue
                    world = base.snapshot()
                    act(world, move)
                    result.nodes += 1
                    actions = prefix + [move]
                    if world.status == "won":
                        record(actions, world.stars_collected)
                        continue
                    if world.decided:
                        continue
                    roll = world.snapshot()
                    roll.run_on(rollout_steps, settle=True)
                    if roll.status == "won" and len(actions) < max_actions:
                        record(actions + [SUCCESS], roll.stars_collected)
                    children.append(_Node(world, actions, _guide(world, roll, len(actions))))
                if done():
                    break
            if done():
                break
        children.sort(key=lambda n: -n.score)
        layer, seen = [], set()
        for child in children:
            key = _state_key(child.world)
            if key in seen:
                continue
            seen.add(key)
            layer.append(child)
            if len(layer) >= beam:
                break
    result.plans = sorted(found.values(), key=lambda p: (-p.stars, len(p.actions)))
    result.best = result.plans[0] if result.plans else None
    return result


def _state_key(world: World) -> tuple:
    return (tuple((round(c.x / 8), round(c.y / 8), round(c.vx / 40), round(c.vy / 40), c.alive)
                  for c in world.candies),
            tuple(sorted((r.source, r.sid) for r in world.ropes)),
            tuple(b.popped for b in world.bubbles), tuple(world.stars), len(world.puffs))


# -- verification -----------------------------------------------------------------------------------


def replay(level: Level, texts: list[str]) -> dict:
    """Play `texts` through the environment (parse and step, as a model's replies would be):
    {"success", "stars", "actions", "t", "outcome"}."""
    from deepphy.envs.cuttherope.env import CutTheRopeEnv

    env = CutTheRopeEnv()
    obs = env.start(level)
    result = None
    for n, text in enumerate(texts, 1):
        action = obs.action_space.parse(text)
        result = env.step(action)
        if result.done:
            return {"success": result.success, "stars": result.stars, "actions": n, "t": env.world.time,
                    "outcome": env.world.reason or ("truncated" if result.truncated else "")}
        obs = result.observation
    return {"success": False, "stars": 0, "actions": len(texts), "t": env.world.time,
            "outcome": "plan ended before the level was decided"}


def play(level: Level, texts: list[str]) -> tuple[bool, int]:
    """(won, stars) of a plan by the environment's rules, without pictures; a plan that ends
    undecided is followed by success() (the world runs on and the game decides)."""
    attempt = Attempt(level)
    for text in texts:
        attempt.play(attempt.space().parse(text))
        if attempt.done:
            break
    else:
        attempt.play(SUCCESS)
    return attempt.world.status == "won", attempt.stars


def trajectory(level: Level, actions: list[CutAction]) -> tuple[World, list[tuple[float, float]], list[str]]:
    """While `actions` play: the final world, the candy positions (every TRAIL_EVERY
    steps; both halves' while there are two) and the events, in words."""
    world = World.from_level(level)
    path: list[tuple[float, float]] = []
    events: list[str] = []
    for a in actions:
        act(world, a)
        path += world.trail
        events += [e.text for e in world.events]
        if world.decided:
            break
    return world, path, events


# -- timing: the sleeps of a plan ---------------------------------------------------------------------


def _with_sleeps(texts: list[str], values: list[float]) -> list[str] | None:
    """`texts` with its sleeps set to `values` (in order); None if one is out of range."""
    out, k = [], 0
    for t in texts:
        action = ANY.parse(t)
        if action.name == "sleep":
            v = round(values[k], 2)
            k += 1
            if not C.SLEEP_MIN <= v <= C.SLEEP_MAX:
                return None
            t = f"sleep({format_seconds(v)})"
        out.append(t)
    return out


def sleeps_of(texts: list[str]) -> list[float]:
    return [a.seconds for a in map(ANY.parse, texts) if a.name == "sleep"]


def robustness(level: Level, texts: list[str], shift: float = 0.1) -> dict:
    """Does the plan still win when its sleeps move by +-shift: each alone, and all
    together? {"variants", "won", "three_stars", "min_stars"} (a plan without sleeps has none)."""
    base = sleeps_of(texts)
    variants = []
    for d in (-shift, shift) if base else ():
        variants.append([v + d for v in base])
        if len(base) > 1:
            variants += [[v + (d if j == k else 0.0) for j, v in enumerate(base)] for k in range(len(base))]
    won = three = 0
    stars = []
    for values in variants:
        plan = _with_sleeps(texts, values)
        ok, s = play(level, plan) if plan else (False, 0)
        won += ok
        three += ok and s == 3
        stars.append(s if ok else 0)
    return {"variants": len(variants), "won": won, "three_stars": three, "min_stars": min(stars, default=3)}


def centre_sleeps(level: Level, texts: list[str], step: float = 0.05, reach: float = 1.0) -> list[str]:
    """The plan with each sleep moved to the middle of the window of values (in `step`s,
    within `reach` s) over which the plan still wins with its stars, the others kept."""
    _, stars = play(level, texts)
    values = sleeps_of(texts)
    for _ in range(2):
        for k in range(len(values)):
            def wins(v: float) -> bool:
                plan = _with_sleeps(texts, values[:k] + [v] + values[k + 1:])
                return plan is not None and play(level, plan) == (True, stars)

            lo = hi = values[k]
            while hi + step <= values[k] + reach and wins(hi + step):
                hi += step
            while lo - step >= values[k] - reach and wins(lo - step):
                lo -= step
            values[k] = round((lo + hi) / 2 / step) * step
    return _with_sleeps(texts, values)
