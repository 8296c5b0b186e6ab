"""The oracle: a beam search over action sequences that finds winning plans.

A plan is a list of actions in the game's own vocabulary. The search builds it one
"move" at a time: optionally a sleep (a grid of durations, `SEARCH_SLEEPS`), then one
element action (cut a pin, cut an active pin, pop a bubble, tap a cushion 1/3/5 times).
Every move is simulated from a snapshot of the world (`World.snapshot`, exact: the world
rebuilds its pymunk space from its own state at every decision) by the environment's own
rules (`env.act`). After each move a
rollout lets the world run on without actions: if the candy reaches Om Nom the plan
(+ `success()` when the win comes after the last action) is a solution. The best
`beam` moves by a guide score (stars touched, closest approach to the mouth, halves'
gap) go on to the next layer. The search stops at its budget (seconds, or simulated moves
for a result independent of the machine), after a 3-star plan, or when no plan can grow
within the decision limit.

Results are verified by replaying the plan's text through the environment itself
(`replay`), so the stored plans are what a model's identical actions would do.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from deepphy.envs.cuttherope import constants as C
from deepphy.envs.cuttherope.env import act
from deepphy.envs.cuttherope.level import Level
from deepphy.envs.cuttherope.sim import World, seconds_to_steps
from deepphy.envs.cuttherope.space import CutAction, CutSpace

SEARCH_SLEEPS = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.3, 1.6, 2.0, 2.5, 3.0)  # sleep before a move (0: none)
ROLLOUT = 4.0  # s the world runs on after a move to see where it leads (<= RUN_ON_CAP)
SUCCESS = CutAction(name="success")


def moves(world: World) -> list[CutAction]:
    """Every element action now: each rope cut alone or with another, bubbles, cushion taps."""
    avail = world.available()
    return CutSpace(num_pins=len(world.level.pins), num_active_pins=len(world.level.active_pins),
                    num_cushions=len(avail["cushions"]), pins=avail["pins"], active_pins=avail["active_pins"],
                    bubbles=avail["bubbles"]).element_actions()


@dataclass
class Plan:
    actions: list[CutAction]
    stars: int

    @property
    def texts(self) -> list[str]:
        space = CutSpace()
        return [space.format(a) for a in self.actions]


@dataclass
class SearchResult:
    best: Plan | None = None
    solutions: int = 0
    nodes: int = 0
    seconds: float = 0.0
    plans: list[Plan] = field(default_factory=list)  # every distinct solution found (best first)


@dataclass
class _Node:
    world: World
    actions: list[CutAction]
    score: float = 0.0


def _guide(world: World, rollout: World, n_actions: int) -> float:
    """Higher is better: stars touched, closeness to the mouth, halves coming together."""
    score = 60.0 * rollout.stars_collected - min(world.min_mouth_distance, rollout.min_mouth_distance)
    if world.level.halves and not any(c.alive and not c.half for c in rollout.candies) and rollout.status != "won":
        score -= 400.0 + min(world.min_join_gap, rollout.min_join_gap)
    if rollout.status == "lost":
        score -= 150.0
    return score - 3.0 * n_actions


def search(level: Level, *, budget_s: float = 30.0, max_nodes: int | None = None, beam: int = 8, want_stars: int = 3,
           max_actions: int = C.MAX_ACTIONS, sleeps: tuple[float, ...] = SEARCH_SLEEPS,
           accept: Callable[[Plan], bool] | None = None) -> SearchResult:
    """Beam search for winning plans of at most `max_actions` actions, within `budget_s`
    seconds and (if given) `max_nodes` simulated moves; the node budget alone makes the
    result independent of the machine's speed. With `accept`, stop at the first solution
    it accepts (and report only accepted ones)."""
    start = time.perf_counter()
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
        return (best >= want_stars or (accept is not None and bool(found))
                or time.perf_counter() - start > budget_s
                or (max_nodes is not None and result.nodes >= max_nodes))

    root = World.from_level(level)
    layer = [_Node(root, [])]
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
                    roll.run_on(rollout_steps)
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
    result.seconds = time.perf_counter() - start
    return result


def _state_key(world: World) -> tuple:
    return (tuple((round(c.x / 8), round(c.y / 8), c.alive) for c in world.candies),
            tuple(sorted((r.source, r.sid) for r in world.ropes)),
            tuple(b.popped for b in world.bubbles), world.stars_collected)


# -- verification and baselines -------------------------------------------------------------------


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


def reference_win_rate(level: Level, rng: np.random.Generator, episodes: int = 100) -> float:
    """How often the reference random agent (space.reference_reply's policy: cut / pop / tap
    once, in uniformly random order, then fail()) wins: a measure of how easy a level is."""
    wins = 0
    for _ in range(episodes):
        world = World.from_level(level)
        tapped: set[int] = set()
        for _ in range(C.MAX_ACTIONS):
            avail = world.available()
            choices = ([CutAction(name="cut_pin", ids=(i,)) for i in avail["pins"]]
                       + [CutAction(name="cut_active_pin", ids=(i,)) for i in avail["active_pins"]]
                       + [CutAction(name="pop_bubble", ids=(i,)) for i in avail["bubbles"]]
                       + [CutAction(name="tap_air_cushion", ids=(i,), times=1) for i in avail["cushions"]
                          if i not in tapped])
            if not choices:
                break
            move = choices[int(rng.integers(len(choices)))]
            if move.name == "tap_air_cushion":
                tapped.add(move.ids[0])
            act(world, move)
            if world.decided:
                break
        else:
            world.run_on(seconds_to_steps(C.RUN_ON_CAP))
        wins += world.status == "won"
    return wins / episodes


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


def path_length(path: list[tuple[float, float]]) -> float:
    return sum(math.dist(p, q) for p, q in zip(path, path[1:]))
