"""Angry Birds' shortcut baselines (deepphy/envs/shortcuts.py): policies that read the world
but understand nothing of it.

- `aim`: each bird straight through the centre of the nearest live pig (nearest to the
  slingshot), at full power, on the flatter of the two ballistic arcs (the game's own
  gravity and launch speed, in closed form; obstacles ignored). A pig that already had that
  very shot and still lives gets the lob (the steep arc) instead, then the flat one again.
- `base`: each bird at full power, on the flatter arc, into the foot of the biggest
  structure: the lower left corner of the largest group of touching blocks (by area), the
  side that faces the slingshot.

Both play the world as it stands before the decision (privileged: the context replays the
attempt's earlier shots), so they are deterministic. `play` runs one against a `World`
directly (the calibration's and the tests' fast path); the registered policies go through
`ShortcutContext.replay()` like any shortcut.
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

import pymunk

from deepphy.envs.angrybirds import constants as C
from deepphy.envs.angrybirds.sim import World
from deepphy.envs.angrybirds.space import ShootSpace
from deepphy.envs.shortcuts import ShortcutContext, ShortcutPolicy

FULL_POWER = C.POWER_MAX
BASE_LIFT = 0.2  # u above the structure's lowest point: the bird meets its bottom layer, not the ground
LAYER = 0.3  # u: blocks whose bottom is this close to the structure's lowest point form its bottom layer
TOUCH = 0.02  # u: blocks whose shapes come this close touch (a settled scene's contacts)

Shot = tuple[float, float]  # (angle, power) as the action space rounds them


def arcs(x: float, y: float, power: float = FULL_POWER) -> tuple[float, float] | None:
    """The launch angles (degrees, flat then steep) whose flight passes through (x, y) at
    launch speed `power` x MAX_LAUNCH_SPEED, or None when (x, y) is out of reach."""
    v, g = power * C.MAX_LAUNCH_SPEED, C.GRAVITY
    dx, dy = x - C.SLING_X, y - C.SLING_Y
    if dx <= 1e-9:
        return None
    disc = v ** 4 - g * (g * dx * dx + 2.0 * dy * v * v)
    if disc < 0.0:
        return None
    root = math.sqrt(disc)
    return (math.degrees(math.atan((v * v - root) / (g * dx))), math.degrees(math.atan((v * v + root) / (g * dx))))


def _shot(angle: float, power: float) -> Shot:
    space = ShootSpace()
    action = space.make(min(max(angle, C.ANGLE_MIN), C.ANGLE_MAX), min(max(power, 0.01), C.POWER_MAX))
    return action.angle, action.power


def flat_shot(x: float, y: float) -> Shot:
    """At full power along the flatter arc through (x, y). A point below the launch so near
    that the flatter arc points downwards: a level shot with the power that passes through
    it. Out of reach: 45 degrees at full power (the farthest throw)."""
    roots = arcs(x, y)
    if roots is None:
        return _shot(45.0, FULL_POWER)
    if roots[0] >= C.ANGLE_MIN:
        return _shot(roots[0], FULL_POWER)
    drop = C.SLING_Y - y  # > 0 here
    speed = (x - C.SLING_X) * math.sqrt(C.GRAVITY / (2.0 * drop))
    return _shot(0.0, speed / C.MAX_LAUNCH_SPEED)


def lob_shot(x: float, y: float) -> Shot:
    """At full power along the steeper arc through (x, y) (out of reach: 45 degrees)."""
    roots = arcs(x, y)
    return _shot(roots[1] if roots is not None else 45.0, FULL_POWER)


def nearest_pig(world):
    pigs = world.alive("pig")
    return min(pigs, key=lambda p: (math.hypot(p.body.position.x - C.SLING_X, p.body.position.y - C.SLING_Y),
                                    p.index)) if pigs else None


def aim_at_pig(world, earlier: Sequence[Shot]) -> Shot:
    """`aim` (module doc)."""
    pig = nearest_pig(world)
    if pig is None:  # not reached in play: the attempt ends with the last pig
        return _shot(45.0, FULL_POWER)
    x, y = pig.body.position
    flat, lob = flat_shot(x, y), lob_shot(x, y)
    return lob if flat in earlier and lob not in earlier else flat


def structures(world) -> list[list]:
    """The groups of touching blocks and crates (pigs do not join them), largest area first
    (ties: nearer the slingshot first)."""
    things = [t for t in world.things if t.alive and t.kind in ("block", "tnt")]
    parent = list(range(len(things)))

    def find(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for i in range(len(things)):
        for j in range(i + 1, len(things)):
            if find(i) != find(j) and _touch(things[i], things[j]):
                parent[find(i)] = find(j)
    groups: dict[int, list] = {}
    for i, t in enumerate(things):
        groups.setdefault(find(i), []).append(t)
    return sorted(groups.values(), key=lambda g: (-sum(_area(t) for t in g), min(_left(t) for t in g)))


def _touch(a, b) -> bool:
    """Whether two things' shapes come within TOUCH of each other (convex shapes: the
    closest points include a corner of one of them, or a circle's centre)."""
    for sa in a.shapes:
        for sb in b.shapes:
            if sa.bb.intersects(_grown(sb.bb)) and min(_gap(sa, sb), _gap(sb, sa)) < TOUCH:
                return True
    return False


def _grown(bb):
    return bb.__class__(bb.left - TOUCH, bb.bottom - TOUCH, bb.right + TOUCH, bb.top + TOUCH)


def _gap(shape, other) -> float:
    """The least distance from `shape`'s corners (a circle: its rim) to `other`."""
    body = shape.body
    if isinstance(shape, pymunk.Circle):
        return other.point_query(body.local_to_world(shape.offset)).distance - shape.radius
    return min(other.point_query(body.local_to_world(v)).distance for v in shape.get_vertices())


def _area(thing) -> float:
    return sum(s.area for s in thing.shapes)


def _left(thing) -> float:
    return min(s.bb.left for s in thing.shapes)


def aim_at_base(world, earlier: Sequence[Shot]) -> Shot:
    """`base` (module doc). No block left: `aim`."""
    groups = structures(world)
    if not groups:
        return aim_at_pig(world, earlier)
    shapes = [s for t in groups[0] for s in t.shapes]
    bottom = min(s.bb.bottom for s in shapes)
    left = min(s.bb.left for s in shapes if s.bb.bottom <= bottom + LAYER)
    return flat_shot(left, bottom + BASE_LIFT)


def play(level, policy: Callable, world=None) -> tuple[object, list[Shot]]:
    """Play a whole attempt of `policy` (aim_at_pig, aim_at_base) on a fresh world of
    `level` (or `world`): the world at the end and the shots taken."""
    world = world if world is not None else World(level)
    shots: list[Shot] = []
    for bird in level.birds:
        shot = policy(world, shots)
        world.shoot(bird, *shot)
        shots.append(shot)
        if world.pigs_left == 0:
            break
    return world, shots


def _as_policy(choose: Callable) -> Callable[[ShortcutContext], str]:
    def policy(ctx: ShortcutContext) -> str:
        env, _ = ctx.replay()
        space = ShootSpace()
        earlier = [(a.angle, a.power) for a in (space.parse(text) for text in ctx.earlier)]
        return space.format(space.make(*choose(env.world, earlier)))

    policy.__doc__ = choose.__doc__
    return policy


POLICIES: dict[str, Callable] = {"aim": aim_at_pig, "base": aim_at_base}  # on a World (`play`)
EXPLOITS = {
    "aim": "each bird at full power straight at the nearest live pig (flat arc; a lob when that shot failed)",
    "base": "each bird at full power into the foot of the biggest structure",
}
SHORTCUTS = {name: ShortcutPolicy(_as_policy(choose), EXPLOITS[name]) for name, choose in POLICIES.items()}
