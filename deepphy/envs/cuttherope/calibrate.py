"""What a level measures: the figures of the calibration report (`deepphy solve --env
cuttherope calibrate`) and of the design checks (`... make`).

- `reference_baseline`: MOCK's reference random agent, episode by episode, with the very
  draws `deepphy run --model mock` makes (seeded by seed, environment, task, run, attempt
  and step: deepphy/agents.py), played by the environment's rules (`env.Attempt`);
- `random_orders`: the exact probability that the reference agent wins, which those
  episodes sample: every sequence of choices it can draw, played out;
- `grid_share`: how many plans of a fixed timing grid win (the stored plan's number of
  element actions, each after a pause from GRID_PAUSES);
- `needs`: which elements the 3-star plan needs: the oracle finds no 3-star plan with the
  element removed, or none that never uses it in an action (a rope cut at once is needed
  by being cut: removing it is the same as cutting it at t = 0); an obstacle (spikes, an
  electric barrier, a spider; bubbles, active pins and walls may be either) cannot be
  needed that way, so it must shut a way out: some plan that wins in the level without it
  loses with it;
- `shortcut_baseline`: a shortcut baseline (shortcuts.py), episode by episode, with the
  very draws `deepphy run --model shortcut-<name>` makes;
- `nudged` (oracle.py): the stored plan with each action alone taken 0.1 s earlier and later;
- `first_moves_that_win`: the element actions that win on their own at t = 0 (a level a
  single first action wins asks for no plan);
- `first_actions_all_win`: every first action, followed by waiting, wins (a level that
  needs no understanding at all);
- `at_rest`: no candy moves in the first second when nothing is done (hooks held still).
"""

from __future__ import annotations

import math

import numpy as np

from deepphy.envs.base import Task
from deepphy.envs.cuttherope import SPEC
from deepphy.envs.cuttherope import constants as C
from deepphy.envs.cuttherope.env import Attempt, CutTheRopeOptions, act
from deepphy.envs.cuttherope.level import Level
from deepphy.envs.cuttherope.shortcuts import SHORTCUTS
from deepphy.envs.shortcuts import PREFIX, ShortcutContext
from deepphy.envs.cuttherope.oracle import ANY, SEARCH_NODES, SUCCESS, Plan, moves, play, search, texts_of
from deepphy.envs.cuttherope.sim import World
from deepphy.envs.cuttherope.space import CutAction
from deepphy.seeding import seeded_rng

ENV = "cuttherope"
BASELINE_EPISODES = 60  # runs 0..59 of MOCK's draws (a 3-run `deepphy run` plays runs 0..2)
GRID_PAUSES = (0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0)  # pauses before each move of the timing grid (0: none)
GRID_MOVES = 3  # at most this many element actions in a grid plan
GRID_PLANS = 400  # grid plans played per level: all of them, or a fixed seeded sample of this many
LATER = (0.5, 1.0, 2.0, 3.0, 5.0, 8.0)  # s: how much later the obstacle test starts (or slows) the stored plan
AT_REST_MOVE = 1.0  # px: a candy that moves less than this in the first second (nothing done) is at rest
# Sequences the exact reference-baseline rate plays out at most: 7 elements' orders (the 88
# levels have at most 24, 0.9 s for all of them).
RANDOM_ORDERS_MAX = 5040
FAIL = CutAction(name="fail")


# -- the reference baseline -------------------------------------------------------------------------


def reference_episode(level: Level, seed: int, run: int) -> tuple[bool, int]:
    """One episode of MOCK's reference baseline on `level` (attempt 1 of run `run`): (won, stars)."""
    attempt = Attempt(level)
    earlier: list[str] = []
    for step in range(1, C.MAX_ACTIONS + 1):
        space = attempt.space()
        rng = seeded_rng("mock", seed, ENV, level.id, run, 1, step)
        action = space.parse(space.reference_reply(rng, earlier))
        attempt.play(action)
        if attempt.done:
            break
        earlier.append(space.format(action))
    return attempt.world.status == "won", attempt.stars


def reference_baseline(level: Level, seed: int = 0, episodes: int = BASELINE_EPISODES) -> dict:
    """{"episodes", "wins", "rate", "stars": [stars of each win], "wins_by_run": [won?]}."""
    outcomes = [reference_episode(level, seed, run) for run in range(episodes)]
    stars = [s for won, s in outcomes if won]
    return {"episodes": episodes, "wins": len(stars), "rate": len(stars) / episodes, "stars": stars,
            "wins_by_run": [won for won, _ in outcomes]}


# -- the shortcut baselines -------------------------------------------------------------------------

RANDOM_SHORTCUTS = {"random-pauses"}  # the shortcuts that draw: played for many episodes; the others once


def shortcut_episode(level: Level, name: str, seed: int, run: int) -> tuple[bool, int]:
    """One episode of shortcut baseline `name` on `level` (attempt 1 of run `run`), with the
    draws of `deepphy run --model shortcut-<name>` (deepphy/agents.py): (won, stars)."""
    policy = SHORTCUTS[name].policy
    attempt = Attempt(level)
    task = Task(env=ENV, id=level.id, group=f"b{level.box}", params={"level": level.id, "state_text": False})
    earlier: list[str] = []
    for step in range(1, C.MAX_ACTIONS + 1):
        space = attempt.space()
        rng = seeded_rng("shortcut", PREFIX + name, seed, ENV, level.id, run, 1, step)  # as agents.shortcut_text
        ctx = ShortcutContext(spec=SPEC, options=CutTheRopeOptions(), task=task, action_space=space,
                              earlier=list(earlier), tried=[], rng=rng)
        action = space.parse(policy(ctx))
        attempt.play(action)
        if attempt.done:
            break
        earlier.append(space.format(action))
    return attempt.world.status == "won", attempt.stars


def shortcut_baseline(level: Level, name: str, seed: int = 0, episodes: int = BASELINE_EPISODES) -> dict:
    """{"episodes", "wins", "rate", "stars": [stars of each win]}: a deterministic shortcut
    plays one episode (every run is the same)."""
    n = episodes if name in RANDOM_SHORTCUTS else 1
    outcomes = [shortcut_episode(level, name, seed, run) for run in range(n)]
    stars = [s for won, s in outcomes if won]
    return {"episodes": n, "wins": len(stars), "rate": len(stars) / n, "stars": stars}


def first_moves_that_win(level: Level) -> list[str]:
    """The element actions that win on their own at t = 0 (then success())."""
    root = World.from_level(level)
    return [text for text in texts_of(moves(root)) if play(level, [text, "success()"])[0]]


class _TooMany(Exception):
    pass


def random_orders(level: Level, limit: int = RANDOM_ORDERS_MAX) -> dict | None:
    """The reference baseline's exact chances on `level`, which its 60 episodes sample: every
    sequence of its choices (one per action, each uniform among those available then) played
    out by the rules, weighted by its probability. {"sequences", "rate": the probability of a
    win, "stars": {stars: probability of a win with them}}; None past `limit` sequences."""
    out: dict = {"sequences": 0, "rate": 0.0, "stars": {}}

    def play_out(prefix: list[CutAction], p: float) -> None:
        attempt = Attempt(level)  # replayed from the start: ~1.4 ms of physics per simulated second
        for action in prefix:
            attempt.play(action)
        choices = [] if attempt.done else attempt.space().reference_choices()
        for choice in choices:
            play_out([*prefix, choice], p / len(choices))
        if choices:
            return
        if not attempt.done:
            attempt.play(FAIL)
        out["sequences"] += 1
        if out["sequences"] > limit:
            raise _TooMany
        if attempt.world.status == "won":
            out["rate"] += p
            out["stars"][attempt.stars] = out["stars"].get(attempt.stars, 0.0) + p

    try:
        play_out([], 1.0)
    except _TooMany:
        return None
    return out


# -- the timing grid ---------------------------------------------------------------------------------


def grid_share(level: Level, element_moves: int) -> dict:
    """Plans of `element_moves` element actions (at most GRID_MOVES), each after a pause from
    GRID_PAUSES, then success(): all of them, or a fixed seeded sample of GRID_PLANS (each
    choice uniform among those at its moment). {"plans", "won", "three_stars"}."""
    k = max(1, min(element_moves, GRID_MOVES))
    rng = seeded_rng("cuttherope-grid", level.id)
    root = World.from_level(level)
    total = _count(root, k)
    won = three = 0
    if total <= GRID_PLANS:
        leaves = _all_leaves(root, k)
    else:
        leaves = (_sample_leaf(root, k, rng) for _ in range(GRID_PLANS))
    plans = 0
    for world in leaves:
        plans += 1
        if not world.decided:
            act(world, SUCCESS)
        won += world.status == "won"
        three += world.status == "won" and world.stars_collected == 3
    return {"plans": plans, "of": total, "won": won, "three_stars": three}


def _pause(world: World, pause: float) -> World:
    w = world.snapshot()
    if pause > 0 and not w.decided:
        act(w, CutAction(name="sleep", seconds=pause))
    return w


def _move(world: World, move: CutAction) -> World:
    w = world.snapshot()
    act(w, move)
    return w


def _count(world: World, k: int) -> int:
    """Leaves of the grid's tree, counted on the first layer's branching (later layers
    have one element fewer to use at most: an estimate that decides enumerate or sample)."""
    n = len(GRID_PAUSES) * max(1, len(moves(world)))
    return n ** k


def _all_leaves(world: World, k: int):
    if k == 0 or world.decided or not moves(world):
        yield world
        return
    for pause in GRID_PAUSES:
        paused = _pause(world, pause)
        options = moves(paused)  # what can be named after the pause (a hat may have snapped a rope)
        if paused.decided or not options:
            yield paused
            continue
        for move in options:
            yield from _all_leaves(_move(paused, move), k - 1)


def _sample_leaf(world: World, k: int, rng: np.random.Generator) -> World:
    for _ in range(k):
        if world.decided or not moves(world):
            break
        world = _pause(world, GRID_PAUSES[int(rng.integers(len(GRID_PAUSES)))])
        options = moves(world)
        if world.decided or not options:
            break
        world = _move(world, options[int(rng.integers(len(options)))])
    return world


# -- what the 3-star plan needs -------------------------------------------------------------------------

KINDS = {  # element kind -> (label letter, the tests that can show it is needed, tried in this order)
    "pins": ("P", ("removed", "unused")), "active_pins": ("A", ("removed", "unused", "obstacle")),
    "bubbles": ("B", ("removed", "unused", "obstacle")), "cushions": ("C", ("unused",)),
    "hats": ("H", ("removed",)), "spikes": ("S", ("obstacle",)), "electrics": ("E", ("obstacle",)),
    "walls": ("W", ("removed", "obstacle")), "spider": ("spider P", ("obstacle",)), "track": ("track P", ("removed",)),
}
ACTED_ON = {"pins": "cut_pin", "active_pins": "cut_active_pin", "bubbles": "pop_bubble",
            "cushions": "tap_air_cushion"}  # kinds whose ids a plan names


def elements(level: Level) -> list[tuple[str, int, str]]:
    """(kind, index, label) of every element of a level, in a fixed order; kinds "spider"
    and "track" name a pin's spider and a hook's track."""
    out = []
    for kind in ("pins", "active_pins", "bubbles", "cushions", "hats", "spikes", "electrics", "walls"):
        out += [(kind, k, f"{KINDS[kind][0]}{k + 1}") for k in range(len(getattr(level, kind)))]
    out += [("spider", k, f"spider P{k + 1}") for k, p in enumerate(level.pins) if p.spider]
    out += [("track", k, f"track P{k + 1}") for k, p in enumerate(level.pins) if p.track]
    return out


def without(level: Level, kind: str, index: int) -> Level:
    """The level with one element taken out (a spider or a track: the pin stays, fixed where
    the hook starts)."""
    if kind in ("spider", "track"):
        pins = list(level.pins)
        pin = pins[index]
        if kind == "spider":
            pins[index] = pin.model_copy(update={"spider": None})
        else:
            pins[index] = pin.model_copy(update={"pos": pin.at(0.0), "track": None})
        return Level.model_validate({**level.model_dump(), "pins": [p.model_dump() for p in pins]})
    items = getattr(level, kind)
    return Level.model_validate({**level.model_dump(),
                                 kind: [e.model_dump() for k, e in enumerate(items) if k != index]})


def _renumber(texts: list[str], kind: str, index: int) -> list[str]:
    """A plan of the level without element `index` of `kind`, in the full level's ids."""
    name = ACTED_ON.get(kind)
    out = []
    for text in texts:
        action = ANY.parse(text)
        if action.name == name:
            action = action.model_copy(update={"ids": tuple(i + (i > index) for i in action.ids)})
        out.append(ANY.format(action))
    return out


def _later(plan: list[str]) -> list[list[str]]:
    """The plan started later, and with each of its sleeps longer: the ways of taking one's
    time that an obstacle (a spider on its way, a barrier that switches) may punish."""
    out = [[f"sleep({t:g})", *plan] for t in LATER]
    for k, text in enumerate(plan):
        action = ANY.parse(text)
        if action.name == "sleep":
            out += [plan[:k] + [f"sleep({min(action.seconds + t, C.SLEEP_MAX):g})"] + plan[k + 1:] for t in LATER]
    return out


def needed(level: Level, kind: str, index: int, max_nodes: int = SEARCH_NODES, plan: list[str] | None = None) -> str:
    """How the 3-star plan needs one element, by the first of its kind's tests that shows it:
    "removed" (no 3-star plan when it is taken out), "unused" (no 3-star plan that never
    names it in an action), "obstacle" (some plan that wins in the level without it loses
    with it: it shuts a way out; `plan`, the stored plan, started later or slowed down, is
    tried first, then the search); "NOT NEEDED" when none does, within the search's budget."""
    for test in KINDS[kind][1]:
        if test == "removed":
            best = search(without(level, kind, index), max_nodes=max_nodes).best
            if best is None or best.stars < 3:
                return test
        elif test == "unused":
            name = ACTED_ON[kind]

            def uses(move: CutAction) -> bool:
                return move.name == name and index + 1 in move.ids
            best = search(level, max_nodes=max_nodes, forbid=uses).best
            if best is None or best.stars < 3:
                return test
        else:
            reduced = without(level, kind, index)

            def blocked(plan: Plan) -> bool:
                return not play(level, _renumber(plan.texts, kind, index))[0]
            if plan is not None and kind not in ACTED_ON and any(
                    play(reduced, v)[0] and not play(level, v)[0] for v in _later(plan)):
                return test
            if search(reduced, max_nodes=max_nodes, want_stars=4, accept=blocked).best:
                return test
    return "NOT NEEDED"


def needs(level: Level, max_nodes: int = SEARCH_NODES) -> dict[str, str]:
    """{label: `needed`'s verdict} for every element of the level."""
    plan = level.solution.actions if level.solution else None
    return {label: needed(level, kind, index, max_nodes, plan) for kind, index, label in elements(level)}


# -- quick looks ----------------------------------------------------------------------------------------


def first_actions_all_win(level: Level) -> bool:
    """Every element action at t = 0, then waiting, wins."""
    root = World.from_level(level)
    return all(play(level, [text, "success()"])[0] for text in texts_of(moves(root)))


def at_rest(level: Level) -> bool:
    """No candy moves more than AT_REST_MOVE in the first second when nothing is done (hooks
    held still where they start: a moving hook moves its candy by design)."""
    for k, pin in enumerate(level.pins):
        if pin.track:
            level = without(level, "track", k)
    world = World.from_level(level)
    start = [(c.x, c.y) for c in world.candies]
    moved = 0.0
    for _ in range(C.STEPS_PER_SECOND):
        world.advance(1)
        moved = max([moved] + [math.dist(p, (c.x, c.y)) for p, c in zip(start, world.candies) if c.alive])
        if world.decided:
            return False
    return moved < AT_REST_MOVE


def element_actions(texts: list[str]) -> int:
    """How many of a plan's actions act on elements (not sleep, success or fail)."""
    return sum(ANY.parse(t).name not in ("sleep", "success", "fail") for t in texts)

