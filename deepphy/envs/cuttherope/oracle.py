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
from deepphy.envs.cuttherope.env import Attempt, CutTheRopeEnv, act, apply, invalid_reason
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


# -- timing: every action of a plan nudged (the declared nudge set) ------------------------------------

NUDGE = 0.1  # s: each element action of a plan alone, this much earlier and later
ROBUST_SHARE = 0.95  # a stored plan is robust when at least this share of its nudged variants win
CENTRE_STEP = 5  # physics steps (0.05 s): the grain on which centre_actions moves an action
CENTRE_REACH = 1.0  # s: how far centre_actions looks for the edges of an action's window


def sleeps_of(texts: list[str]) -> list[float]:
    return [a.seconds for a in map(ANY.parse, texts) if a.name == "sleep"]


def timed(texts: list[str]) -> list[tuple[int, CutAction]]:
    """A plan as its element actions and the world's step at which each is taken (a sleep
    runs its seconds, any other action ACTION_INTERVAL); success() and fail() end it."""
    out, step = [], 0
    for text in texts:
        action = ANY.parse(text)
        if action.name in ("success", "fail"):
            break
        if action.name == "sleep":
            step += seconds_to_steps(action.seconds)
        else:
            out.append((step, action))
            step += seconds_to_steps(C.ACTION_INTERVAL)
    return out


def untimed(schedule: list[tuple[int, CutAction]]) -> list[str] | None:
    """The plan (its text, ending with success()) that takes each action at its step; None
    when the steps cannot be written (a gap shorter than ACTION_INTERVAL, or one that a sleep
    cannot fill: shorter than SLEEP_MIN or longer than SLEEP_MAX)."""
    out, now = [], 0
    interval = seconds_to_steps(C.ACTION_INTERVAL)
    for step, action in schedule:
        gap = (step - now) / C.STEPS_PER_SECOND
        if gap < 0:
            return None
        if gap > 0:
            if not C.SLEEP_MIN <= round(gap, 2) <= C.SLEEP_MAX:
                return None
            out.append(f"sleep({format_seconds(round(gap, 2))})")
        out.append(ANY.format(action))
        now = step + interval
    return out + ["success()"]


def play_timed(level: Level, schedule: list[tuple[int, CutAction]]) -> tuple[bool, int]:
    """(won, stars) when each action is taken at its step (in order), the world then running
    on as after the plan's last action (ACTION_INTERVAL, then at most RUN_ON_CAP)."""
    world = World.from_level(level)
    for step, action in schedule:
        world.advance(step - world.step_count)
        if world.decided:
            break
        if invalid_reason(world, action) is not None:
            return False, 0
        apply(world, action)
    world.run_on(seconds_to_steps(C.ACTION_INTERVAL + C.RUN_ON_CAP))
    won = world.status == "won"
    return won, world.stars_collected if won else 0


def nudged(level: Level, texts: list[str], shift: float = NUDGE) -> dict:
    """The declared nudge set: each element action of the plan alone taken `shift` s earlier
    and later on the world's clock, the others where they were (an action that would come
    before t = 0 is left out; the unnudged plan does not count). {"variants", "won",
    "three_stars", "share" (of variants won; 1 when there are none), "weakest": the action
    whose nudges win least, with its share}."""
    schedule = timed(texts)
    d = seconds_to_steps(shift)
    won = three = variants = 0
    per_action = []
    for k, (step, action) in enumerate(schedule):
        wins = tries = 0
        for delta in (-d, d):
            if step + delta < 0:
                continue
            ok, stars = play_timed(level, schedule[:k] + [(step + delta, action)] + schedule[k + 1:])
            tries += 1
            wins += ok
            three += ok and stars == 3
        variants += tries
        won += wins
        if tries:
            per_action.append((wins / tries, ANY.format(action)))
    weakest = min(per_action, default=(1.0, None))
    return {"variants": variants, "won": won, "three_stars": three, "share": won / variants if variants else 1.0,
            "weakest": {"action": weakest[1], "share": weakest[0]}}


def robust(level: Level, texts: list[str]) -> bool:
    return nudged(level, texts)["share"] >= ROBUST_SHARE


def centre_actions(level: Level, texts: list[str]) -> list[str]:
    """The plan with each action moved (the others kept where they are on the world's clock)
    to the middle of its window: the times, on a CENTRE_STEP grain within CENTRE_REACH, at
    which the plan still wins with its stars (the writable one nearest the middle). An
    action at t = 0 stays there."""
    goal = play(level, texts)
    schedule = timed(texts)
    reach = seconds_to_steps(CENTRE_REACH)
    for _ in range(2):
        for k, (step, action) in enumerate(schedule):
            if step == 0:
                continue  # an action at once stays at once (it has no earlier)

            def moved(at: int) -> list[tuple[int, CutAction]]:
                return schedule[:k] + [(at, action)] + schedule[k + 1:]

            def wins(at: int) -> bool:
                return play_timed(level, moved(at)) == goal

            lo = hi = step
            while hi + CENTRE_STEP <= step + reach and wins(hi + CENTRE_STEP):
                hi += CENTRE_STEP
            while lo - CENTRE_STEP >= max(0, step - reach) and wins(lo - CENTRE_STEP):
                lo -= CENTRE_STEP
            # the writable time nearest the middle of the window (a gap after an action is
            # ACTION_INTERVAL or a sleep of at least SLEEP_MIN)
            writable = [at for at in range(lo, hi + 1, CENTRE_STEP) if untimed(moved(at)) is not None]
            if writable:
                schedule[k] = (min(writable, key=lambda at: (abs(2 * at - lo - hi), at)), action)
    plan = untimed(schedule)
    return plan if plan is not None and play(level, plan) == goal else texts
