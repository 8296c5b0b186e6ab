"""The Angry Birds world in pymunk: structures, pigs, TNT, birds, damage, explosions.

A level's start state is its data built in a fixed order and settled for SETTLE_TIME with
nobody taking damage (`settled_poses`, computed once per process and level content); every
`World` is then built fresh at those poses, at rest, so every attempt starts from the same
state, bit for bit, without paying for the settling again. `shoot` launches the next bird
and simulates until the shot is over (below).

Damage comes from the physics, never from scripts: each new contact (the collision handler's
`begin`, which also notes how fast the two bodies close along its normal) is looked up after
the step that solved it, its impulse J read from the arbiter (what a post-solve handler sees
on a first contact, without a Python call for every contact of every step). A bird's hit on
a block or crate deals Science Birds'  closing speed x BIRD_DAMAGE_MASS x factor x
IMPACT_DAMAGE - defense; every other contact  J x IMPACT_DAMAGE x factor - defense
(constants.py). Resting contacts are not first contacts, so a standing structure
takes no damage however heavy it is; what moves and hits does: birds, falling blocks,
toppling towers, bodies thrown by an explosion. A body pinned against the ground takes the
whole impulse of what lands on it (the solver stops both), so heavy blocks crush.
Destroyed bodies leave the space after the step; a destroyed TNT crate explodes.

Round bodies (birds, pigs, logs) have rolling resistance (pymunk has none: a circle would
roll on forever): a motor to the static body holds their spin with a bounded torque
(ROLL_RESISTANCE); a bird touching anything also loses speed (BIRD_SKID). Other bodies
have a small spin brake of the same kind (SPIN_BRAKE, angular drag).

Birds do not collide with each other (one shape-filter group), so the blue bird's three
can split side by side. A spent bird (one that has hit something) leaves the world once it
lies still, or SPENT_BIRD_TIME after its first hit at the latest; a shot ends when no bird
of it is left and every other body has been at rest for REST_HOLD (or at SHOT_MAX_TIME,
a safety cap). So the settled scene is the state the next shot starts from.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import pymunk

from deepphy.envs.angrybirds import constants as C
from deepphy.envs.angrybirds.levels import Level

BIRD_GROUP = 1
# Housekeeping that need not run every step (bodies move at most ~0.2 u per step):
SKID_EVERY = 4  # steps between applications of a bird's skid
CHECK_EVERY = 6  # steps between checks for rest, spent birds and bodies leaving the world


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
    hit_time: float = 0.0  # birds: shot time of the first hit
    left_world: bool = False  # gone beyond the edges of the world
    still: int = 0  # birds: steps lying still so far (counted at the checks)
    brake: pymunk.Constraint | None = None  # rolling resistance or spin brake (see World._new)

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
    ability_acted: bool = False  # the bird dashed, split or exploded
    first_hit: str | None = None  # what the bird hit first
    first_hit_time: float | None = None
    birds_hit: int = 0  # birds of the shot (three for a split blue bird) that hit something
    birds_left_world: int = 0  # birds of the shot that flew out of the world
    sim_time: float = 0.0
    at_rest: bool = True  # False: stopped at SHOT_MAX_TIME
    trails: list[list[tuple[float, float]]] = field(default_factory=list)
    snapshots: list[Snapshot] = field(default_factory=list)
    film: list[Snapshot] = field(default_factory=list)  # a replay's pictures (shoot's `film_every`)

    @property
    def blocks_total(self) -> int:
        return sum(self.blocks_destroyed.values())


@functools.lru_cache(maxsize=256)
def _settled(content: str) -> tuple[tuple[float, float, float], ...]:
    world = World(Level.model_validate_json(content), settle=False)
    for _ in range(round(C.SETTLE_TIME / C.DT)):
        world._step()
    return tuple((t.body.position.x, t.body.position.y, t.body.angle) for t in world.things)


def settled_poses(level: Level) -> tuple[tuple[float, float, float], ...]:
    """(x, y, angle in radians) of every block, pig and crate once the level has settled."""
    return _settled(level.model_dump_json(exclude={"oracle"}))  # a new plan does not change it


class World:
    def __init__(self, level: Level, *, settle: bool = True, abilities: bool = True) -> None:
        """The level at its start state; `settle=False`: at the positions its data gives
        (what the start state is computed from). `abilities=False`: the birds fly without
        their abilities (no dash, split or blast), for the oracle's check whether a level
        needs them."""
        self.level = level
        self.abilities = abilities
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
        self._new_contacts: list[tuple[pymunk.Shape, pymunk.Shape, float]] = []
        self._birds_flying: list[Thing] = []  # birds of the current shot
        self._steps = 0
        self.pigs_killed = 0
        self.blocks_destroyed = 0

        self._add_ground()
        for p in level.platforms:
            self._add_platform(p.x, p.y, p.w, p.h, p.angle)
        for t in level.terrain:
            self._add_terrain(t.points)
        as_given = [(b.x, b.y, math.radians(b.angle)) for b in level.blocks] + \
            [(p.x, p.y, 0.0) for p in level.pigs] + [(t.x, t.y, 0.0) for t in level.tnt]
        poses = iter(settled_poses(level) if settle else as_given)
        for b in level.blocks:
            self._add_block(b.shape, b.material, *next(poses))
        for p in level.pigs:
            self._add_pig(p.size, *next(poses))
        for t in level.tnt:
            self._add_tnt(*next(poses))
        handler = space.add_default_collision_handler()
        handler.begin = self._begin
        self._damage_on = settle

    # -- building ------------------------------------------------------------------------

    def _add_ground(self) -> None:
        body = self.space.static_body
        depth = 5.0
        ground = pymunk.Poly.create_box_bb(
            body, pymunk.BB(-10.0, C.GROUND_Y - depth, C.WORLD_W + 10.0, C.GROUND_Y)
        )
        ground.friction, ground.elasticity = C.GROUND_FRICTION, C.GROUND_ELASTICITY
        self.space.add(ground)
        self._ground = ground

    def _add_platform(self, x: float, y: float, w: float, h: float, angle: float) -> None:
        body = pymunk.Body(body_type=pymunk.Body.STATIC)
        body.position, body.angle = (x, y), math.radians(angle)
        shape = pymunk.Poly.create_box(body, (w, h))
        shape.friction, shape.elasticity = C.TERRAIN_MATERIAL["friction"], C.TERRAIN_MATERIAL["elasticity"]
        self.space.add(body, shape)

    def _add_terrain(self, points: list[tuple[float, float]]) -> None:
        shape = pymunk.Poly(self.space.static_body, points)
        shape.friction, shape.elasticity = C.TERRAIN_MATERIAL["friction"], C.TERRAIN_MATERIAL["elasticity"]
        self.space.add(shape)

    def _new(self, kind: str, name: str, body: pymunk.Body, shapes: list[pymunk.Shape], **kw) -> Thing:
        thing = Thing(index=len(self.things), kind=kind, name=name, body=body, shapes=shapes, **kw)
        self.space.add(body, *shapes)
        for s in shapes:
            self._by_shape[s] = thing
        self.things.append(thing)
        # Every body has a motor to the static body that holds its spin with a bounded torque.
        # Round bodies: rolling resistance, the torque that slows a disk rolling on flat
        # ground by `a` (a m r (1 + I / (m r^2)) = 1.5 a m r), solved with the contacts: a pig
        # stays put on a gentle slope, a log rolls down a steep one. Other bodies: a small
        # spin brake (angular drag), so a plank rocking on a pig comes to rest.
        if thing.radius:
            key = "bird" if kind == "bird" else "pig" if kind == "pig" else "log"
            torque = 1.5 * C.ROLL_RESISTANCE[key] * body.mass * thing.radius
        else:
            reach = max(math.hypot(x, y) for poly in thing.polygons for x, y in poly)
            torque = C.SPIN_BRAKE * body.mass * C.GRAVITY * reach
        brake = pymunk.SimpleMotor(body, self.space.static_body, 0.0)
        brake.max_force = torque
        self.space.add(brake)
        thing.brake = brake
        if kind == "bird":
            self._birds_flying.append(thing)
        return thing

    def _add_block(self, shape: str, material: str, x: float, y: float, angle: float) -> Thing:
        """A block at (x, y), turned `angle` radians."""
        m = C.MATERIALS[material]
        w, h = C.BLOCK_SIZES[shape]
        body = pymunk.Body()
        body.position, body.angle = (x, y), angle
        polygons: list[list[tuple[float, float]]] = []
        radius = 0.0
        if shape in C.ROUND_SHAPES:
            radius = w / 2
            shapes: list[pymunk.Shape] = [pymunk.Circle(body, radius)]
        elif shape == "square_hole":
            t = C.HOLLOW_WALL
            walls = [  # bottom, top, left, right
                (-w / 2, -h / 2, w / 2, -h / 2 + t), (-w / 2, h / 2 - t, w / 2, h / 2),
                (-w / 2, -h / 2 + t, -w / 2 + t, h / 2 - t), (w / 2 - t, -h / 2 + t, w / 2, h / 2 - t),
            ]
            polygons = [[(a, b), (c, b), (c, d), (a, d)] for a, b, c, d in walls]
            shapes = [pymunk.Poly(body, p) for p in polygons]
        elif shape == "triangle":
            polygons = [[(-w / 2, -h / 2), (w / 2, -h / 2), (-w / 2, h / 2)]]
            shapes = [pymunk.Poly(body, polygons[0])]
        elif shape == "triangle_hole":  # bottom, left and slanted walls (w == h)
            a, t = w / 2, C.HOLLOW_WALL
            d = t * math.sqrt(2.0)  # the slanted wall's inner edge, measured along x
            polygons = [
                [(-a, -a), (a, -a), (a - t, -a + t), (-a, -a + t)],
                [(-a, -a + t), (-a + t, -a + t), (-a + t, a - t), (-a, a)],
                [(a - t, -a + t), (-a + t, a - t), (-a + t, a - t - d), (a - t - d, -a + t)],
            ]
            shapes = [pymunk.Poly(body, p) for p in polygons]
        else:
            polygons = [[(-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2)]]
            shapes = [pymunk.Poly(body, polygons[0])]
        for s in shapes:
            s.density, s.friction, s.elasticity = m["density"], m["friction"], m["elasticity"]
        hp = float(C.BLOCK_HIT_POINTS[shape][material])
        return self._new("block", f"{material} {shape.replace('_', ' ')}", body, shapes, hp=hp, max_hp=hp,
                         defense=m["defense"], material=material, polygons=polygons, radius=radius)

    def _add_pig(self, size: str, x: float, y: float, angle: float = 0.0) -> Thing:
        r = C.PIG_RADIUS[size]
        body = pymunk.Body()
        body.position, body.angle = (x, y), angle
        shape = pymunk.Circle(body, r)
        shape.density, shape.friction, shape.elasticity = C.PIG_DENSITY, C.PIG_FRICTION, C.PIG_ELASTICITY
        hp = C.PIG_HIT_POINTS[size]
        return self._new("pig", f"{size} pig", body, [shape], hp=hp, max_hp=hp, defense=C.PIG_DEFENSE, radius=r)

    def _add_tnt(self, x: float, y: float, angle: float = 0.0) -> Thing:
        s = C.TNT_SIZE
        body = pymunk.Body()
        body.position, body.angle = (x, y), angle
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
            for s1, s2, speed in contacts:
                self._hit(s1, s2, speed)
        if self._steps % SKID_EVERY == 0 and self._birds_flying:
            self._skid()
        self._after_step()

    def _skid(self) -> None:
        """A bird touching something loses speed (it digs in; it does not skid like a puck)."""
        cut = C.BIRD_SKID * C.DT * SKID_EVERY
        for bird in self._birds_flying:
            body = bird.body
            speed = body.velocity.length
            if bird.alive and speed > 0.0 and _touching(body):
                body.velocity = body.velocity * (max(speed - cut, 0.0) / speed)

    def _begin(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> bool:
        if self._damage_on:
            s1, s2 = arbiter.shapes
            if s1 in self._by_shape or s2 in self._by_shape:
                self._new_contacts.append((s1, s2, _closing_speed(arbiter)))
        return True

    def _hit(self, s1: pymunk.Shape, s2: pymunk.Shape, speed: float) -> None:
        """A contact that began in the last step (`speed`: how fast the two closed along its
        normal as it began): a bird's first hit, and damage (module doc)."""
        a, b = self._by_shape.get(s1), self._by_shape.get(s2)
        if (a is not None and not a.alive) or (b is not None and not b.alive):
            return
        bird = a if a is not None and a.kind == "bird" else b if b is not None and b.kind == "bird" else None
        if bird is not None and not bird.hit:
            other, shape = (b, s2) if bird is a else (a, s1)
            self._first_hit(bird, other.name if other is not None else self._fixed_name(shape))
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
        for target, other in ((a, b), (b, a)):
            if target is None or target.kind == "bird" or not target.alive:
                continue
            if bird is not None and other is bird and target.kind != "pig":
                # Science Birds' rule for a bird's hit on a block or crate: the speed it
                # comes in with, whatever the block weighs (a light block barely stops a
                # bird, so its impulse would undercount the blow).
                factor = C.BIRD_MATERIAL_FACTOR[bird.bird].get(target.material or "", 1.0)
                amount = speed * C.BIRD_DAMAGE_MASS[bird.bird] * factor * C.IMPACT_DAMAGE
            else:
                factor = 1.0 if bird is not None and other is bird else C.NON_BIRD_FACTOR
                amount = impulse * C.IMPACT_DAMAGE * factor
            self._damage(target, amount - target.defense)

    def _first_hit(self, bird: Thing, what: str) -> None:
        bird.hit = True
        bird.hit_time = self._shot_time
        shot = self._shot
        if shot is not None and shot.first_hit is None:
            shot.first_hit = what
            shot.first_hit_time = self._shot_time
        if bird.bird == "black" and bird.alive and self.abilities:
            self._explode_bird(bird)
            if shot is not None:
                shot.ability_acted = True

    def _fixed_name(self, shape: pymunk.Shape) -> str:
        return "the ground" if shape is self._ground else "a fixed platform"

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
        self.space.remove(thing.brake, thing.body, *thing.shapes)

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
              snapshot_every: float = 0.1, film_every: float | None = None) -> ShotResult:
        """Launch `bird` from the slingshot and simulate until the shot is over: every bird
        of it gone and the scene at rest (or SHOT_MAX_TIME). `record`: keep a snapshot every
        `snapshot_every` s for pictures. `film_every`: also one every `film_every` s in
        `shot.film`, for a replay (looking on changes nothing of the shot)."""
        shot = ShotResult(bird=bird)
        self._shot, self._shot_time = shot, 0.0
        first = self._add_bird(bird, (C.SLING_X, C.SLING_Y), C.launch_velocity(angle, power))
        birds = [first]
        trails: list[list[tuple[float, float]]] = [[(C.SLING_X, C.SLING_Y)]]
        ability_pending = self.abilities and bird in ("yellow", "blue")
        steps = 0
        max_steps = round(C.SHOT_MAX_TIME / C.DT)
        trail_every = max(1, round(C.TRAIL_EVERY / C.DT))
        snap_every = max(1, round(snapshot_every / C.DT))
        min_steps = round(C.SHOT_MIN_TIME / C.DT)
        hold_steps = round(C.REST_HOLD / C.DT)
        bird_hold_steps = round(C.BIRD_REST_HOLD / C.DT)
        still = 0
        if record:
            shot.snapshots.append(Snapshot(0.0, self.poses(), [list(t) for t in trails]))
        film_steps = max(1, round(film_every / C.DT)) if film_every else 0
        film_blasts: list[tuple[float, float, float]] = []  # since the last picture: a blast lasts one step
        if film_steps:
            shot.film.append(Snapshot(0.0, self.poses(), [list(t) for t in trails]))
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
                    shot.ability_acted = True
                    shot.ability = "the yellow bird dashed forward"
                else:
                    birds += self._split(first)
                    shot.ability_acted = True
                    trails += [list(trails[0]) for _ in range(len(birds) - len(trails))]
                    shot.ability = "the blue bird split into three"
            if bird == "black" and self.abilities and first.alive and t >= C.BLACK_FUSE - 1e-9:
                self._explode_bird(first)
                self._after_step()
                shot.ability_acted = True
                shot.ability = "the black bird exploded in the air (its fuse ran out)"
            if steps % CHECK_EVERY == 0:
                self._housekeeping(birds, bird_hold_steps)
            if steps % trail_every == 0:
                for b, trail in zip(birds, trails):
                    if b.alive and not b.hit:
                        trail.append((b.body.position.x, b.body.position.y))
            if record and (steps % snap_every == 0 or self._frame_blasts):
                shot.snapshots.append(Snapshot(t, self.poses(), [list(tr) for tr in trails], self._frame_blasts))
            if film_steps:
                film_blasts += self._frame_blasts
                if steps % film_steps == 0:
                    shot.film.append(Snapshot(t, self.poses(), [list(tr) for tr in trails], film_blasts))
                    film_blasts = []
            self._frame_blasts = []
            if steps >= min_steps and steps % CHECK_EVERY == 0:
                gone = not any(b.alive for b in birds)
                still = still + CHECK_EVERY if gone and self._at_rest() else 0
                if still >= hold_steps:
                    break
        else:
            shot.at_rest = False
        if bird == "black" and self.abilities and not shot.ability:
            shot.ability = "the black bird exploded on impact" if first.hit else ""
        for b in birds:  # only at the safety cap
            if b.alive:
                self._remove(b)
        shot.birds_hit = sum(b.hit for b in birds)
        shot.birds_left_world = sum(b.left_world for b in birds)
        shot.sim_time = steps * C.DT
        shot.trails = trails
        if record and shot.snapshots[-1].t != shot.sim_time:
            shot.snapshots.append(Snapshot(shot.sim_time, self.poses(), [list(tr) for tr in trails]))
        self._shot = None
        self._birds_flying = []
        return shot

    def _housekeeping(self, birds: list[Thing], bird_hold_steps: int) -> None:
        """Remove what left the world (a pig pushed out of the picture dies) and spent birds."""
        for thing in self.things:
            if thing.alive and self._out_of_world(thing):
                thing.left_world = True
                self._remove(thing)
                if thing.kind != "bird":
                    self._count_destroyed(thing)
        for b in birds:
            if not (b.alive and b.hit):
                continue
            body = b.body
            lying = body.velocity.length < C.REST_SPEED and abs(body.angular_velocity) < C.REST_SPIN and _touching(body)
            b.still = b.still + CHECK_EVERY if lying else 0
            if b.still >= bird_hold_steps or self._shot_time - b.hit_time >= C.SPENT_BIRD_TIME - 1e-9:
                self._remove(b)

    def advance(self, seconds: float) -> None:
        """Simulate without launching anything (damage on): for tests and tools."""
        for _ in range(round(seconds / C.DT)):
            self._step()

    def add_block(self, shape: str, material: str, x: float, y: float, angle: float = 0.0) -> Thing:
        """Add a block (turned `angle` degrees) to a built world (for tests and tools; levels
        list their blocks)."""
        return self._add_block(shape, material, x, y, math.radians(angle))

    def add_pig(self, size: str, x: float, y: float) -> Thing:
        """Add a pig to a built world (for tests and tools; levels list their pigs)."""
        return self._add_pig(size, x, y)

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
        return not any(_moving(t.body) for t in self.things if t.alive)

    def moving(self) -> list[Thing]:
        """The live bodies that still move (for tests and tools)."""
        return [t for t in self.things if t.alive and _moving(t.body)]


def _closing_speed(arbiter: pymunk.Arbiter) -> float:
    """How fast the two bodies of a new contact approach each other along its normal, at its
    first point (before the solver separates them)."""
    points = arbiter.contact_point_set.points
    if not points:
        return 0.0
    a, b = (s.body for s in arbiter.shapes)
    p = points[0].point_a
    relative = b.velocity_at_world_point(p) - a.velocity_at_world_point(p)
    return abs(relative.dot(arbiter.normal))


def _moving(body: pymunk.Body) -> bool:
    """Faster than the rest thresholds."""
    return body.velocity.length > C.REST_SPEED or abs(body.angular_velocity) > C.REST_SPIN


def _touching(body: pymunk.Body) -> bool:
    """Whether the body has a contact with anything this step."""
    touching = False

    def seen(arbiter: pymunk.Arbiter) -> None:
        nonlocal touching
        touching = True

    body.each_arbiter(seen)
    return touching
