"""The Angry Birds world in pymunk: structures, pigs, TNT, birds, damage, explosions.

A `World` is built from a level's data in a fixed order and settled (SETTLE_TIME, nobody
takes damage), so every attempt starts from the same state, bit for bit. `shoot` launches
the next bird and simulates until the scene is at rest (or SHOT_MAX_TIME).

Damage comes from the physics, never from scripts: each new contact (the collision handler's
`begin`) is looked up after the step that solved it, its impulse J read from the arbiter
(what a post-solve handler sees on a first contact, without a Python call for every
contact of every step), and each body with hit points takes  J x IMPACT_DAMAGE x factor -
defense  (constants.py). Resting contacts are not
first contacts, so a standing structure takes no damage however heavy it is; what moves
and hits does: birds, falling blocks, toppling towers, bodies thrown by an explosion.
Destroyed bodies leave the space after the step; a destroyed TNT crate explodes.

Birds do not collide with each other (one shape-filter group), so the blue bird's three
can split side by side. Spent birds are removed when the shot ends.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pymunk

from deepphy.envs.angrybirds import constants as C
from deepphy.envs.angrybirds.levels import Level

BIRD_GROUP = 1
# Housekeeping that need not run every step (bodies move at most ~0.2 u per step):
ROLL_EVERY = 4  # steps between applications of the rolling resistance
CHECK_EVERY = 6  # steps between checks for rest and for bodies leaving the world
_ROLL_KEEP = math.exp(-C.ROLLING_DAMPING * C.DT * ROLL_EVERY)


@dataclass(eq=False)
class Thing:
    """A body with hit points (block, pig, TNT) or a bird."""

    index: int  # creation order: the renderer's and the records' handle
    kind: str  # "block" | "pig" | "tnt" | "bird"
    name: str  # "wood rect_medium", "small pig", "TNT", "red bird"
    body: pymunk.Body
    shapes: list[pymunk.Shape]
    hp: float = math.inf
    max_hp: float = math.inf
    defense: float = 0.0
    material: str | None = None  # blocks
    bird: str | None = None  # birds: red | yellow | blue | black
    # Geometry for drawing, in body coordinates: polygons, or a circle radius.
    polygons: list[list[tuple[float, float]]] = field(default_factory=list)
    radius: float = 0.0
    alive: bool = True
    hit: bool = False  # birds: touched something since launch

    @property
    def damage(self) -> float:
        """0 (intact) .. 1 (about to break)."""
        if not math.isfinite(self.max_hp) or self.max_hp <= 0:
            return 0.0
        return min(max(1.0 - self.hp / self.max_hp, 0.0), 1.0)


@dataclass
class Pose:
    """Where a thing is at one moment (what the renderer draws)."""

    thing: Thing
    x: float
    y: float
    angle: float
    damage: float


@dataclass
class Snapshot:
    t: float  # s after launch
    poses: list[Pose]
    trails: list[list[tuple[float, float]]]  # one per bird of the shot, so far
    blasts: list[tuple[float, float, float]] = field(default_factory=list)  # (x, y, radius) this frame


@dataclass
class ShotResult:
    bird: str
    pigs_killed: int = 0
    blocks_destroyed: dict[str, int] = field(default_factory=dict)  # by material, "tnt" for crates
    ability: str = ""  # what the bird's ability did, in words
    first_hit: str | None = None  # what the bird hit first
    first_hit_time: float | None = None
    sim_time: float = 0.0
    at_rest: bool = True  # False: stopped at SHOT_MAX_TIME
    trails: list[list[tuple[float, float]]] = field(default_factory=list)
    snapshots: list[Snapshot] = field(default_factory=list)

    @property
    def blocks_total(self) -> int:
        return sum(self.blocks_destroyed.values())


class World:
    def __init__(self, level: Level) -> None:
        self.level = level
        space = pymunk.Space()
        space.gravity = (0.0, -C.GRAVITY)
        space.iterations = C.ITERATIONS
        self.space = space
        self.things: list[Thing] = []
        self._by_shape: dict[pymunk.Shape, Thing] = {}
        self._damage_on = False
        self._pending: list[Thing] = []  # destroyed this step, removed after it
        self._blasts: list[tuple[float, float, dict[str, float], Thing | None]] = []
        self._shot: ShotResult | None = None
        self._shot_time = 0.0
        self._frame_blasts: list[tuple[float, float, float]] = []
        self._new_contacts: list[tuple[pymunk.Shape, pymunk.Shape]] = []
        self._round: list[Thing] = []  # bodies that roll (rolling resistance)
        self._steps = 0
        self.pigs_killed = 0
        self.blocks_destroyed = 0

        self._add_ground()
        for p in level.platforms:
            self._add_platform(p.x, p.y, p.w, p.h, p.angle)
        for b in level.blocks:
            self._add_block(b.shape, b.material, b.x, b.y, b.angle)
        for p in level.pigs:
            self._add_pig(p.size, p.x, p.y)
        for t in level.tnt:
            self._add_tnt(t.x, t.y)
        handler = space.add_default_collision_handler()
        handler.begin = self._begin

        for _ in range(round(C.SETTLE_TIME / C.DT)):
            self._step()
        for thing in self.things:
            thing.body.velocity = (0.0, 0.0)
            thing.body.angular_velocity = 0.0
        self._damage_on = True

    # -- building ------------------------------------------------------------------------

    def _add_ground(self) -> None:
        body = self.space.static_body
        depth = 5.0
        ground = pymunk.Poly.create_box_bb(
            body, pymunk.BB(-10.0, C.GROUND_Y - depth, C.WORLD_W + 10.0, C.GROUND_Y)
        )
        ground.friction, ground.elasticity = C.GROUND_FRICTION, C.GROUND_ELASTICITY
        self.space.add(ground)

    def _add_platform(self, x: float, y: float, w: float, h: float, angle: float) -> None:
        body = pymunk.Body(body_type=pymunk.Body.STATIC)
        body.position, body.angle = (x, y), math.radians(angle)
        shape = pymunk.Poly.create_box(body, (w, h))
        shape.friction, shape.elasticity = C.PLATFORM_MATERIAL["friction"], C.PLATFORM_MATERIAL["elasticity"]
        self.space.add(body, shape)

    def _new(self, kind: str, name: str, body: pymunk.Body, shapes: list[pymunk.Shape], **kw) -> Thing:
        thing = Thing(index=len(self.things), kind=kind, name=name, body=body, shapes=shapes, **kw)
        self.space.add(body, *shapes)
        for s in shapes:
            self._by_shape[s] = thing
        self.things.append(thing)
        if thing.radius:
            self._round.append(thing)
        return thing

    def _add_block(self, shape: str, material: str, x: float, y: float, angle: float) -> Thing:
        m = C.MATERIALS[material]
        w, h = C.BLOCK_SIZES[shape]
        body = pymunk.Body()
        body.position, body.angle = (x, y), math.radians(angle)
        polygons: list[list[tuple[float, float]]] = []
        radius = 0.0
        if shape in C.ROUND_SHAPES:
            radius = w / 2
            shapes: list[pymunk.Shape] = [pymunk.Circle(body, radius)]
        elif shape == "square_hole":
            t = C.SQUARE_HOLE_WALL
            walls = [  # bottom, top, left, right
                (-w / 2, -h / 2, w / 2, -h / 2 + t), (-w / 2, h / 2 - t, w / 2, h / 2),
                (-w / 2, -h / 2 + t, -w / 2 + t, h / 2 - t), (w / 2 - t, -h / 2 + t, w / 2, h / 2 - t),
            ]
            polygons = [[(a, b), (c, b), (c, d), (a, d)] for a, b, c, d in walls]
            shapes = [pymunk.Poly(body, p) for p in polygons]
        elif shape == "triangle":
            polygons = [[(-w / 2, -h / 2), (w / 2, -h / 2), (-w / 2, h / 2)]]
            shapes = [pymunk.Poly(body, polygons[0])]
        else:
            polygons = [[(-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2)]]
            shapes = [pymunk.Poly(body, polygons[0])]
        for s in shapes:
            s.density, s.friction, s.elasticity = m["density"], m["friction"], m["elasticity"]
        hp = float(C.BLOCK_HIT_POINTS[shape][material])
        return self._new("block", f"{material} {shape.replace('_', ' ')}", body, shapes, hp=hp, max_hp=hp,
                         defense=m["defense"], material=material, polygons=polygons, radius=radius)

    def _add_pig(self, size: str, x: float, y: float) -> Thing:
        r = C.PIG_RADIUS[size]
        body = pymunk.Body()
        body.position = (x, y)
        shape = pymunk.Circle(body, r)
        shape.density, shape.friction, shape.elasticity = C.PIG_DENSITY, C.PIG_FRICTION, C.PIG_ELASTICITY
        hp = C.PIG_HIT_POINTS[size]
        return self._new("pig", f"{size} pig", body, [shape], hp=hp, max_hp=hp, defense=C.PIG_DEFENSE, radius=r)

    def _add_tnt(self, x: float, y: float) -> Thing:
        s = C.TNT_SIZE
        body = pymunk.Body()
        body.position = (x, y)
        poly = [(-s / 2, -s / 2), (s / 2, -s / 2), (s / 2, s / 2), (-s / 2, s / 2)]
        shape = pymunk.Poly(body, poly)
        shape.density, shape.friction, shape.elasticity = C.TNT_DENSITY, 0.8, 0.1
        return self._new("tnt", "TNT", body, [shape], hp=C.TNT_HIT_POINTS, max_hp=C.TNT_HIT_POINTS,
                         defense=C.TNT_DEFENSE, polygons=[poly])

    def _add_bird(self, kind: str, position: tuple[float, float], velocity: tuple[float, float]) -> Thing:
        r = C.BIRD_RADIUS[kind]
        body = pymunk.Body()
        body.position, body.velocity = position, velocity
        shape = pymunk.Circle(body, r)
        shape.mass = C.BIRD_MASS[kind]
        shape.friction, shape.elasticity = C.BIRD_FRICTION, C.BIRD_ELASTICITY
        shape.filter = pymunk.ShapeFilter(group=BIRD_GROUP)
        return self._new("bird", C.BIRD_NAMES[kind], body, [shape], bird=kind, radius=r)

    # -- state ---------------------------------------------------------------------------

    def alive(self, kind: str) -> list[Thing]:
        return [t for t in self.things if t.alive and t.kind == kind]

    @property
    def pigs_left(self) -> int:
        return sum(1 for t in self.things if t.alive and t.kind == "pig")

    def score(self, shots_used: int) -> int:
        """The score so far; the unused birds count once every pig is dead."""
        score = C.SCORE_PIG * self.pigs_killed + C.SCORE_BLOCK * self.blocks_destroyed
        if self.pigs_left == 0:
            score += C.SCORE_UNUSED_BIRD * (len(self.level.birds) - shots_used)
        return score

    def poses(self) -> list[Pose]:
        return [Pose(t, t.body.position.x, t.body.position.y, t.body.angle, t.damage) for t in self.things if t.alive]

    def state(self) -> list[tuple[int, float, float, float, float, float, float, float]]:
        """Every live body's exact state (for determinism checks)."""
        out = []
        for t in self.things:
            if t.alive:
                b = t.body
                out.append((t.index, b.position.x, b.position.y, b.angle, b.velocity.x, b.velocity.y,
                            b.angular_velocity, t.hp))
        return out

    # -- damage ----------------------------------------------------------------------------

    def _step(self) -> None:
        """One physics step, then its consequences: damage from new contacts, rolling
        resistance, removals and explosions."""
        self.space.step(C.DT)
        self._steps += 1
        if self._new_contacts:
            contacts, self._new_contacts = self._new_contacts, []
            for s1, s2 in contacts:
                self._hit(s1, s2)
        if self._steps % ROLL_EVERY == 0:  # pymunk has no rolling resistance: pigs and logs would roll forever
            for thing in self._round:
                if thing.alive:
                    thing.body.angular_velocity *= _ROLL_KEEP
        self._after_step()

    def _begin(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> bool:
        if self._damage_on:
            s1, s2 = arbiter.shapes
            if s1 in self._by_shape or s2 in self._by_shape:
                self._new_contacts.append((s1, s2))
        return True

    def _hit(self, s1: pymunk.Shape, s2: pymunk.Shape) -> None:
        """Damage from a contact that began in the last step, by the impulse that resolved it."""
        a, b = self._by_shape.get(s1), self._by_shape.get(s2)
        if (a is not None and not a.alive) or (b is not None and not b.alive):
            return
        body = (a or b).body
        found: list[float] = []

        def read(arbiter: pymunk.Arbiter) -> None:
            shapes = arbiter.shapes
            if (shapes[0] is s1 and shapes[1] is s2) or (shapes[0] is s2 and shapes[1] is s1):
                found.append(arbiter.total_impulse.length)

        body.each_arbiter(read)
        if not found:
            return  # touched and parted within the step
        impulse = found[0]
        bird = a if a is not None and a.kind == "bird" else b if b is not None and b.kind == "bird" else None
        for target, other in ((a, b), (b, a)):
            if target is None or target.kind == "bird" or not target.alive:
                continue
            if bird is not None and other is bird:
                factor = C.BIRD_MATERIAL_FACTOR[bird.bird].get(target.material or "", 1.0)
            else:
                factor = C.NON_BIRD_FACTOR
            self._damage(target, impulse * C.IMPACT_DAMAGE * factor - target.defense)
        if bird is not None and not bird.hit:
            bird.hit = True
            other = b if bird is a else a
            shot = self._shot
            if shot is not None and shot.first_hit is None:
                shot.first_hit = other.name if other is not None else "the ground"
                shot.first_hit_time = self._shot_time
            if bird.bird == "black" and bird.alive:
                self._explode_bird(bird)

    def _damage(self, thing: Thing, amount: float) -> None:
        if amount <= 0 or not thing.alive or thing in self._pending:
            return
        thing.hp -= amount
        if thing.hp <= 0:
            self._pending.append(thing)

    def _explode_bird(self, bird: Thing) -> None:
        p = bird.body.position
        self._blasts.append((p.x, p.y, C.BLACK_BLAST, bird))
        if bird not in self._pending:
            self._pending.append(bird)

    def _remove(self, thing: Thing) -> None:
        thing.alive = False
        self.space.remove(thing.body, *thing.shapes)

    def _after_step(self) -> None:
        """Remove what broke during the step; set off explosions (which may break more)."""
        while self._pending or self._blasts:
            while self._pending:
                thing = self._pending.pop(0)
                if not thing.alive:
                    continue
                self._remove(thing)
                self._count_destroyed(thing)
                if thing.kind == "tnt":
                    p = thing.body.position
                    self._blasts.append((p.x, p.y, C.TNT_BLAST, thing))
            if self._blasts:
                x, y, blast, source = self._blasts.pop(0)
                self._blast(x, y, blast, source)

    def _count_destroyed(self, thing: Thing) -> None:
        if thing.kind == "pig":
            self.pigs_killed += 1
            if self._shot is not None:
                self._shot.pigs_killed += 1
        elif thing.kind in ("block", "tnt"):
            self.blocks_destroyed += 1
            if self._shot is not None:
                key = thing.material or "tnt"
                self._shot.blocks_destroyed[key] = self._shot.blocks_destroyed.get(key, 0) + 1

    def _blast(self, x: float, y: float, blast: dict[str, float], source: Thing | None) -> None:
        radius, push, damage = blast["radius"], blast["impulse"], blast["damage"]
        self._frame_blasts.append((x, y, radius))
        for thing in self.things:
            if not thing.alive or thing is source:
                continue
            body = thing.body
            dx, dy = body.position.x - x, body.position.y - y
            d = math.hypot(dx, dy)
            if d >= radius:
                continue
            falloff = 1.0 - d / radius
            if d > 1e-9:
                body.apply_impulse_at_world_point((dx / d * push * falloff, dy / d * push * falloff),
                                                  body.local_to_world(body.center_of_gravity))
            if thing.kind != "bird":
                self._damage(thing, damage * falloff)

    # -- a shot ------------------------------------------------------------------------------

    def shoot(self, bird: str, angle: float, power: float, *, record: bool = False,
              snapshot_every: float = 0.1) -> ShotResult:
        """Launch `bird` from the slingshot and simulate until the scene is at rest (or
        SHOT_MAX_TIME). `record`: keep a snapshot every `snapshot_every` s for pictures."""
        shot = ShotResult(bird=bird)
        self._shot, self._shot_time = shot, 0.0
        first = self._add_bird(bird, (C.SLING_X, C.SLING_Y), C.launch_velocity(angle, power))
        birds = [first]
        trails: list[list[tuple[float, float]]] = [[(C.SLING_X, C.SLING_Y)]]
        ability_pending = bird in ("yellow", "blue")
        steps = 0
        max_steps = round(C.SHOT_MAX_TIME / C.DT)
        trail_every = max(1, round(C.TRAIL_EVERY / C.DT))
        snap_every = max(1, round(snapshot_every / C.DT))
        min_steps = round(C.SHOT_MIN_TIME / C.DT)
        hold_steps = round(C.REST_HOLD / C.DT)
        still = 0
        if record:
            shot.snapshots.append(Snapshot(0.0, self.poses(), [list(t) for t in trails]))
        while steps < max_steps:
            self._shot_time = (steps + 1) * C.DT
            self._step()
            steps += 1
            t = self._shot_time
            if ability_pending and t >= C.ABILITY_TIME - 1e-9:
                ability_pending = False
                if not first.alive or first.hit:
                    shot.ability = f"the {C.BIRD_NAMES[bird]} hit something before its ability could act"
                elif bird == "yellow":
                    self._dash(first)
                    shot.ability = "the yellow bird dashed forward"
                else:
                    birds += self._split(first)
                    trails += [list(trails[0]) for _ in range(len(birds) - len(trails))]
                    shot.ability = "the blue bird split into three"
            if bird == "black" and first.alive and t >= C.BLACK_FUSE - 1e-9:
                self._explode_bird(first)
                self._after_step()
                shot.ability = "the black bird exploded in the air (its fuse ran out)"
            if steps % CHECK_EVERY == 0:
                for thing in self.things:
                    if thing.alive and self._out_of_world(thing):
                        self._remove(thing)
                        if thing.kind != "bird":  # a pig pushed out of the picture dies
                            self._count_destroyed(thing)
            if steps % trail_every == 0:
                for b, trail in zip(birds, trails):
                    if b.alive and not b.hit:
                        trail.append((b.body.position.x, b.body.position.y))
            if record and (steps % snap_every == 0 or self._frame_blasts):
                shot.snapshots.append(Snapshot(t, self.poses(), [list(tr) for tr in trails], self._frame_blasts))
            self._frame_blasts = []
            if steps >= min_steps and steps % CHECK_EVERY == 0:
                still = still + CHECK_EVERY if self._at_rest() else 0
                if still >= hold_steps:
                    break
        else:
            shot.at_rest = False
        if bird == "black" and not shot.ability:
            shot.ability = "the black bird exploded on impact" if first.hit else ""
        for b in birds:
            if b.alive:
                self._remove(b)
        shot.sim_time = steps * C.DT
        shot.trails = trails
        self._shot = None
        return shot

    def advance(self, seconds: float) -> None:
        """Simulate without launching anything (damage on): for tests and tools."""
        for _ in range(round(seconds / C.DT)):
            self._step()

    def add_block(self, shape: str, material: str, x: float, y: float, angle: float = 0.0) -> Thing:
        """Add a block to a built world (for tests and tools; levels list their blocks)."""
        return self._add_block(shape, material, x, y, angle)

    def _dash(self, bird: Thing) -> None:
        v = bird.body.velocity
        speed = v.length
        if speed > 1e-9:
            bird.body.velocity = v * ((speed + C.YELLOW_BOOST) / speed)

    def _split(self, bird: Thing) -> list[Thing]:
        v = bird.body.velocity
        p = bird.body.position
        out = []
        for sign in (1, -1):  # above, then below
            out.append(self._add_bird("blue", (p.x, p.y), v.rotated_degrees(sign * C.BLUE_SPLIT_DEGREES)))
        return out

    def _out_of_world(self, thing: Thing) -> bool:
        x, y = thing.body.position
        m = C.OUT_OF_WORLD_MARGIN
        return x < -m or x > C.WORLD_W + m or y < C.GROUND_Y - m

    def _at_rest(self) -> bool:
        for t in self.things:
            if t.alive:
                b = t.body
                if b.velocity.length > C.REST_SPEED or abs(b.angular_velocity) > C.REST_SPIN:
                    return False
        return True
