"""The Cut the Rope world: its state, the elements' rules, and pymunk for the dynamics.

The state of a level in play is plain Python data (`World`): candies, ropes, bubbles,
spiders, active pins, collected stars, scheduled puffs, the clock in physics steps.
`World.advance(steps)` builds a pymunk space from that state (fixed order), steps it, and
writes the state back. So a world restored from `snapshot()` continues exactly as the
original would (the oracle's search relies on it), and nothing depends on a pymunk space
living across decisions (the project's determinism rule: never copy a space).

Dynamics (constants.py has every number):
- a candy is a pymunk body (a solid disc) under gravity; its circle bounces off and rolls
  on walls (static segments); candies do not collide with each other (two halves join);
- a rope is an elastic segment from its pin to the candy centre: it pulls nothing while
  slack (shorter than its rest length) and pulls like a stiff damped spring once stretched
  beyond it, so it swings the candy, gives and bounces back when jerked taut, and a rope that
  starts stretched contracts and throws the candy. Its pull is set as the body's force
  before each step, computed where pymunk will have moved the body (pymunk moves bodies
  before it updates velocities): symplectic Euler, which keeps a swing's energy but for a
  drag (ROPE_DRAG) while a rope pulls, so that swings die down as in the game. Ropes pass
  through everything (as in the web game); cutting one removes it, so the candy flies on
  with the swing's velocity. A hook on a track moves its rope's pin;
- a bubble that captures the candy replaces gravity by a lift with drag (velocity relaxes
  to BUBBLE_RISE_SPEED upward); it carries the candy until popped;
- a puff of an air cushion changes the velocity of a candy inside the cushion's column, by
  PUFF_SPEED at the nozzle decaying linearly to 0 at PUFF_RANGE;
- a magic hat: the candy moving into a hat's opening leaves the paired hat's opening along
  that hat's direction at HAT_SPEED_FACTOR x its speed; the ropes holding it snap;
- spikes and live electric segments destroy the candy that comes within HAZARD_REACH;
- a spider crawls from its pin along the rope at SPIDER_SPEED and takes the candy when it
  arrives; cutting its rope removes it;
- an active pin attaches a new rope (length = the distance at that moment) when a candy
  centre enters its circle;
- two halves join into one candy when they touch (momentum conserved, ropes and bubbles
  kept); Om Nom eats a whole candy the moment it touches his drawn disc; a half that touches
  him is lost.
Contacts are checked along each step's path (segment distances), so fast candies do not
tunnel through stars, hazards or Om Nom.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Callable

import pymunk

from deepphy.envs.cuttherope import constants as C
from deepphy.envs.cuttherope.level import Level, PinSpec

PUFF_DELAY_STEPS = round(C.PUFF_DELAY * C.STEPS_PER_SECOND)
PUFF_GAP_STEPS = round(C.PUFF_GAP * C.STEPS_PER_SECOND)
ROPE_K = C.ROPE_STIFFNESS * C.CANDY_MASS * C.GRAVITY  # force per unit of stretch
ROPE_C = C.ROPE_DAMPING * C.CANDY_MASS  # force per unit/s of stretching speed
SETTLE_CHECK = 10  # steps between two looks of run_on(settle=True) at whether anything still moves
SETTLE_SPEED = 1.0  # px/s: slower than this at two looks, SETTLE_CHECK steps apart, is at rest


def seconds_to_steps(seconds: float) -> int:
    return round(seconds * C.STEPS_PER_SECOND)


def direction(angle_deg: float) -> tuple[float, float]:
    """Unit vector on the screen (y down) for an angle counter-clockwise from right."""
    a = math.radians(angle_deg)
    return math.cos(a), -math.sin(a)


# -- state ------------------------------------------------------------------------------------


@dataclass
class Candy:
    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    spin: float = 0.0  # angular velocity (rad/s): it rolls on walls
    half: bool = False
    alive: bool = True  # False once eaten, destroyed, lost, or joined into a whole candy

    @property
    def radius(self) -> float:
        return C.HALF_RADIUS if self.half else C.CANDY_RADIUS

    @property
    def mass(self) -> float:
        return C.HALF_MASS if self.half else C.CANDY_MASS


@dataclass(eq=False)  # ropes are told apart by identity
class Rope:
    source: str  # "pin" or "active"
    sid: int  # id (1-based) of its pin or active pin
    ax: float  # anchor (the pin) now; a hook on a track moves it
    ay: float
    length: float  # rest length: the rope pulls once the candy is farther than this
    candy: int  # index into World.candies


@dataclass
class Spider:
    pin: int  # id of the pin whose rope it crawls down
    delay: float  # s after the start before it moves
    crawled: float = 0.0  # units from the pin along the rope
    gone: bool = False  # its rope was cut or snapped


@dataclass
class Bubble:
    x: float
    y: float
    candy: int | None = None  # the candy it carries
    popped: bool = False


@dataclass
class ActivePin:
    x: float
    y: float
    radius: float
    state: str = "armed"  # armed -> attached -> cut; or armed -> removed (cut before it caught the candy)


@dataclass
class Event:
    step: int
    text: str


class Geometry:
    """A level's fixed elements in the form the rules read every step (shared, never copied)."""

    def __init__(self, level: Level) -> None:
        self.stars = [tuple(s) for s in level.stars]
        self.hazards = []  # (electric index or None, a, b, bounding box)
        for k, h in [(None, s) for s in level.spikes] + list(enumerate(level.electrics)):
            lo_x, hi_x = min(h.a[0], h.b[0]), max(h.a[0], h.b[0])
            lo_y, hi_y = min(h.a[1], h.b[1]), max(h.a[1], h.b[1])
            self.hazards.append((k, tuple(h.a), tuple(h.b), (lo_x, lo_y, hi_x, hi_y)))
        self.hats = []  # (pair index, opening, facing, the other hat's opening, its facing)
        for k, pair in enumerate(level.hats):
            for h in (0, 1):
                here, there = pair.hats[h], pair.hats[1 - h]
                self.hats.append((k, tuple(here.pos), direction(here.angle), tuple(there.pos), direction(there.angle)))
        self.cushions = [(tuple(c.pos), direction(c.angle)) for c in level.cushions]
        self.hooks = {i: p for i, p in enumerate(level.pins, 1) if p.track is not None}
        self.om_nom = tuple(level.om_nom)


@dataclass
class World:
    """One level in play. Build with `World.from_level(level)`."""

    level: Level
    geo: Geometry
    step_count: int = 0
    candies: list[Candy] = field(default_factory=list)
    ropes: list[Rope] = field(default_factory=list)
    spiders: list[Spider] = field(default_factory=list)
    bubbles: list[Bubble] = field(default_factory=list)
    active_pins: list[ActivePin] = field(default_factory=list)
    stars: list[bool] = field(default_factory=list)  # collected?
    puffs: list[tuple[int, int]] = field(default_factory=list)  # (step, cushion index) still to come
    status: str = "playing"  # playing | won | lost
    reason: str = ""  # how it was won or lost, in words
    events: list[Event] = field(default_factory=list)  # what happened, for the feedback
    trail: list[tuple[float, float]] = field(default_factory=list)  # candy positions during the last advance
    min_mouth_distance: float = math.inf  # closest a whole candy's centre came to Om Nom's (the oracle's guide)
    min_join_gap: float = math.inf  # closest the two halves came, edge to edge (the oracle's guide)
    # Called after every physics step of `advance` (a replay's camera; it must only look):
    watch: Callable[["World"], None] | None = field(default=None, compare=False, repr=False)

    @classmethod
    def from_level(cls, level: Level) -> "World":
        halves = level.halves
        world = cls(level=level, geo=Geometry(level))
        world.candies = [Candy(x=c.pos[0], y=c.pos[1], vx=c.velocity[0], vy=c.velocity[1], half=halves)
                         for c in level.candies]
        world.ropes = [Rope("pin", i, *p.at(0.0), level.rope_length(i - 1), p.candy) for i, p in enumerate(level.pins, 1)]
        world.spiders = [Spider(i, p.spider.delay) for i, p in enumerate(level.pins, 1) if p.spider]
        world.bubbles = [Bubble(b.pos[0], b.pos[1]) for b in level.bubbles]
        world.active_pins = [ActivePin(a.pos[0], a.pos[1], a.radius) for a in level.active_pins]
        world.stars = [False] * len(level.stars)
        return world

    # -- snapshots (the oracle) -------------------------------------------------------------

    def snapshot(self) -> "World":
        """An independent copy that continues exactly as this world would."""
        shared = self.level, self.geo  # frozen: share, don't copy
        self.level = self.geo = None
        try:
            clone = copy.deepcopy(self)
        finally:
            self.level, self.geo = shared
        clone.level, clone.geo = shared
        return clone

    # -- queries ----------------------------------------------------------------------------

    @property
    def time(self) -> float:
        return self.step_count / C.STEPS_PER_SECOND

    @property
    def decided(self) -> bool:
        return self.status != "playing"

    @property
    def stars_collected(self) -> int:
        return sum(self.stars)

    def rope_of_pin(self, pin: int) -> Rope | None:
        return next((r for r in self.ropes if r.source == "pin" and r.sid == pin), None)

    def rope_of_active_pin(self, pin: int) -> Rope | None:
        return next((r for r in self.ropes if r.source == "active" and r.sid == pin), None)

    def hook(self, rope: Rope) -> PinSpec | None:
        """The pin spec of a rope whose pin moves on a track (None for a fixed pin)."""
        return self.geo.hooks.get(rope.sid) if rope.source == "pin" else None

    def rope_pull(self, rope: Rope) -> tuple[float, float, float]:
        """(tension in force units, unit vector from the pin to the candy): the rope's pull on
        its candy now; 0 when slack (a rope never pushes)."""
        c = self.candies[rope.candy]
        hook = self.hook(rope)
        avx, avy = hook.velocity(self.time) if hook else (0.0, 0.0)
        return _pull(c.x - rope.ax, c.y - rope.ay, c.vx - avx, c.vy - avy, rope.length)

    def rope_tension(self, rope: Rope) -> float:
        """What the rope pulls now, in weights of a whole candy."""
        return self.rope_pull(rope)[0] / (C.CANDY_MASS * C.GRAVITY)

    def rope_stretch(self, rope: Rope) -> float:
        """How far the candy is beyond the rope's rest length (negative: slack by that much)."""
        c = self.candies[rope.candy]
        return math.hypot(c.x - rope.ax, c.y - rope.ay) - rope.length

    def available(self) -> dict[str, list[int]]:
        """Ids that an action can name now: pins whose rope is still attached, active pins
        not yet cut (waiting or holding a rope), bubbles not popped, every air cushion."""
        return {
            "pins": sorted(r.sid for r in self.ropes if r.source == "pin"),
            "active_pins": [i for i, a in enumerate(self.active_pins, 1) if a.state in ("armed", "attached")],
            "bubbles": [i for i, b in enumerate(self.bubbles, 1) if not b.popped],
            "cushions": list(range(1, len(self.level.cushions) + 1)),
        }

    def electric_live(self, index: int, step: int | None = None) -> bool:
        e = self.level.electrics[index]
        t = (self.step_count if step is None else step) / C.STEPS_PER_SECOND
        return (t + e.phase) % e.period < e.on

    def spider_position(self, spider: Spider) -> float:
        """Fraction of its rope the spider has crawled (0 at the pin, 1 at the candy)."""
        rope = self.rope_of_pin(spider.pin)
        if rope is None:
            return 0.0
        return min(1.0, spider.crawled / self.rope_span(rope))

    def rope_span(self, rope: Rope) -> float:
        """The rope's length now: its rest length, or longer while stretched."""
        c = self.candies[rope.candy]
        hook = self.hook(rope)
        ax, ay = hook.at(self.time) if hook else (rope.ax, rope.ay)
        return max(rope.length, math.hypot(c.x - ax, c.y - ay), 1e-9)

    # -- actions ----------------------------------------------------------------------------

    def cut_pin(self, pin: int) -> str:
        rope = self.rope_of_pin(pin)
        assert rope is not None, f"pin {pin} has no rope"
        self.ropes.remove(rope)
        words = f"the rope of pin P{pin} is cut"
        for s in self.spiders:
            if s.pin == pin and not s.gone:
                s.gone = True
                words += " (its spider falls away)"
        return words

    def cut_active_pin(self, pin: int) -> str:
        active = self.active_pins[pin - 1]
        if active.state == "attached":
            rope = self.rope_of_active_pin(pin)
            if rope is not None:
                self.ropes.remove(rope)
            active.state = "cut"
            return f"the rope of active pin A{pin} is cut"
        assert active.state == "armed", f"active pin {pin} is {active.state}"
        active.state = "removed"
        return f"active pin A{pin} is removed before it caught the candy"

    def pop_bubble(self, bubble: int) -> str:
        b = self.bubbles[bubble - 1]
        assert not b.popped, f"bubble {bubble} is already popped"
        b.popped = True
        held, b.candy = b.candy, None
        return f"bubble B{bubble} pops" + (" and releases the candy" if held is not None else " (it held nothing)")

    def tap_air_cushion(self, cushion: int, times: int) -> str:
        first = self.step_count + PUFF_DELAY_STEPS
        self.puffs += [(first + k * PUFF_GAP_STEPS, cushion - 1) for k in range(times)]
        self.puffs.sort()
        return f"air cushion C{cushion} puffs {times} time{'s' if times > 1 else ''}"

    # -- dynamics ---------------------------------------------------------------------------

    def advance(self, steps: int, settle: bool = False) -> None:
        """Run the world for `steps` physics steps, or until the outcome is decided; with
        `settle`, also stop once nothing can change any more (`at_rest`)."""
        self.events = []
        self.trail = []
        if self.decided or steps <= 0:
            return
        space, bodies = self._build_space()
        end = self.step_count + steps
        candies = self.candies
        last_look = None
        while self.step_count < end:
            if self.puffs and self.puffs[0][0] <= self.step_count:
                self._apply_puffs(bodies)
            self._pull(bodies)
            before = [(c.x, c.y) for c in candies]
            space.step(C.DT)
            self.step_count += 1
            for i, body in bodies.items():
                c = candies[i]
                c.x, c.y = body.position
                c.vx, c.vy = body.velocity
                c.spin = body.angular_velocity
            changed = self._rules(before)
            if self.step_count % C.TRAIL_EVERY == 0 or self.decided:
                self.trail += [(candies[i].x, candies[i].y) for i in bodies]  # alive at the step's start
            if self.watch is not None:
                self.watch(self)
            if self.decided:
                break
            if changed:
                self._sync_space(space, bodies)
            if settle and self.step_count % SETTLE_CHECK == 0:
                look = [(c.x, c.y) for c in candies if c.alive] if self.at_rest() else None
                if look is not None and last_look is not None and all(
                        abs(a[0] - b[0]) + abs(a[1] - b[1]) < SETTLE_SPEED * SETTLE_CHECK * C.DT
                        for a, b in zip(look, last_look)):
                    break  # at rest at two looks, and it did not move between them
                last_look = look
        self.place_attachments()

    def place_attachments(self) -> None:
        """Hooked ropes' ends and carried bubbles where they are now (the steps leave them
        for the end of `advance`: only drawing and the text read them)."""
        for rope in self.ropes:
            hook = self.hook(rope)
            if hook:
                rope.ax, rope.ay = hook.at(self.time)
        self.sync_bubbles()

    def run_on(self, max_steps: int, settle: bool = False) -> None:
        """Run without actions until the outcome is decided or `max_steps` have passed (with
        `settle`, or until nothing can change any more)."""
        self.advance(max_steps, settle=settle)

    def at_rest(self) -> bool:
        """Nothing moves and nothing will: every candy slower than SETTLE_SPEED, no bubble
        carrying one, no puff to come, no spider on its way, no rope on a moving hook."""
        if self.puffs or any(b.candy is not None and not b.popped for b in self.bubbles):
            return False
        if any(not s.gone and self.rope_of_pin(s.pin) is not None for s in self.spiders):
            return False
        if any(self.hook(r) for r in self.ropes):
            return False
        return all(abs(c.vx) + abs(c.vy) < SETTLE_SPEED for c in self.candies if c.alive)

    def _build_space(self):
        space = pymunk.Space()
        space.gravity = (0.0, C.GRAVITY)
        space.iterations = C.SOLVER_ITERATIONS
        for wall in self.level.walls:
            shape = pymunk.Segment(space.static_body, wall.a, wall.b, C.WALL_RADIUS)
            shape.elasticity, shape.friction = 1.0, 1.0
            space.add(shape)
        bodies: dict[int, pymunk.Body] = {}
        for i, c in enumerate(self.candies):
            if c.alive:
                bodies[i] = _add_body(space, c)
        self._set_buoyancy(bodies)
        return space, bodies

    def _pull(self, bodies: dict[int, pymunk.Body]) -> None:
        """Each rope's pull on its candy for the next step, computed where pymunk will have
        moved the body when it updates its velocity (pymunk clears forces after a step)."""
        if not self.ropes:
            return
        t = (self.step_count + 1) * C.DT
        forces: dict[int, list[float]] = {}
        for rope in self.ropes:
            c = self.candies[rope.candy]
            px, py = c.x + c.vx * C.DT, c.y + c.vy * C.DT
            hook = self.geo.hooks.get(rope.sid) if rope.source == "pin" and self.geo.hooks else None
            if hook is None:
                tension, ux, uy = _pull(px - rope.ax, py - rope.ay, c.vx, c.vy, rope.length)
            else:
                (ax, ay), (avx, avy) = hook.at(t), hook.velocity(t)
                tension, ux, uy = _pull(px - ax, py - ay, c.vx - avx, c.vy - avy, rope.length)
            if tension > 0.0:
                f = forces.setdefault(rope.candy, [0.0, 0.0])
                f[0] -= tension * ux
                f[1] -= tension * uy
        for i, (fx, fy) in forces.items():
            c = self.candies[i]
            drag = C.ROPE_DRAG * c.mass  # the swing dies down (once per candy, however many ropes pull)
            bodies[i].force = (fx - drag * c.vx, fy - drag * c.vy)

    def _set_buoyancy(self, bodies: dict[int, pymunk.Body]) -> None:
        carried = {b.candy for b in self.bubbles if b.candy is not None and not b.popped}
        for i, body in bodies.items():
            body.velocity_func = _buoyant if i in carried else pymunk.Body.update_velocity

    def _sync_space(self, space: pymunk.Space, bodies: dict[int, pymunk.Body]) -> None:
        """After a rule changed bubbles or candies: make the space match the state
        (positions and velocities of bodies that stay are kept as they are)."""
        for i in list(bodies):
            c = self.candies[i]
            if not c.alive:
                body = bodies.pop(i)
                space.remove(body, *body.shapes)
            else:  # a teleport may have moved it
                bodies[i].position = (c.x, c.y)
                bodies[i].velocity = (c.vx, c.vy)
                bodies[i].angular_velocity = c.spin
        for i, c in enumerate(self.candies):
            if c.alive and i not in bodies:
                bodies[i] = _add_body(space, c)
        self._set_buoyancy(bodies)

    def _apply_puffs(self, bodies: dict[int, pymunk.Body]) -> None:
        while self.puffs and self.puffs[0][0] <= self.step_count:
            _, k = self.puffs.pop(0)
            (cx, cy), (dx, dy) = self.geo.cushions[k]
            for i, body in bodies.items():
                c = self.candies[i]
                rx, ry = c.x - cx, c.y - cy
                along = rx * dx + ry * dy
                across = abs(rx * dy - ry * dx)
                if 0.0 <= along <= C.PUFF_RANGE and across <= C.PUFF_WIDTH / 2:
                    dv = C.PUFF_SPEED * (1.0 - along / C.PUFF_RANGE)
                    c.vx, c.vy = c.vx + dv * dx, c.vy + dv * dy
                    body.velocity = (c.vx, c.vy)

    # -- the rules, checked after every physics step --------------------------------------------

    def _event(self, text: str) -> None:
        self.events.append(Event(self.step_count, text))

    def _lose(self, reason: str) -> None:
        self.status, self.reason = "lost", reason
        self._event(reason)

    def _rules(self, before: list[tuple[float, float]]) -> bool:
        """Apply every element's rule along the step's paths; True when bubbles or candies
        changed so that the pymunk space must be rebuilt. Each check first compares cheap
        bounds: this runs every step."""
        geo, level = self.geo, self.level
        changed = False
        t = self.step_count

        for i, c in enumerate(self.candies):
            if not c.alive:
                continue
            what = _named(c)
            p, q = before[i], (c.x, c.y)
            move = abs(q[0] - p[0]) + abs(q[1] - p[1])
            r = c.radius
            # hazards and the edge of the screen
            for k, a, b, (lo_x, lo_y, hi_x, hi_y) in geo.hazards:
                reach = C.HAZARD_REACH + move
                if not (lo_x - reach <= c.x <= hi_x + reach and lo_y - reach <= c.y <= hi_y + reach):
                    continue
                if k is not None and not self.electric_live(k, t):
                    continue
                if _segment_distance(p, q, a, b) < C.HAZARD_REACH:
                    c.alive = False
                    self._lose(f"{what} hit spikes" if k is None else f"{what} hit a live electric barrier")
                    return True
            m = C.OFFSCREEN_MARGIN
            if not (-m <= c.x <= C.WIDTH + m and -m <= c.y <= C.HEIGHT + m):
                c.alive = False
                self._lose(f"{what} left the screen")
                return True
            # stars
            for k, (sx, sy) in enumerate(geo.stars):
                if not self.stars[k] and abs(sx - c.x) + abs(sy - c.y) < 2 * (C.STAR_RADIUS + r + move):
                    if _point_segment_distance((sx, sy), p, q) < C.STAR_RADIUS + r:
                        self.stars[k] = True
                        self._event(f"star collected ({sum(self.stars)} of {len(self.stars)})")
            # bubbles capture
            if self.bubbles and not any(b.candy == i for b in self.bubbles if not b.popped):
                for k, b in enumerate(self.bubbles):
                    if b.popped or b.candy is not None:
                        continue
                    if abs(b.x - c.x) + abs(b.y - c.y) < 2 * (C.BUBBLE_CAPTURE + move) and \
                            _point_segment_distance((b.x, b.y), p, q) < C.BUBBLE_CAPTURE:
                        b.candy = i
                        changed = True
                        self._event(f"bubble B{k + 1} captured {what}")
                        break
            # magic hats
            for pair, (hx, hy), (fx, fy), (ox, oy), (gx, gy) in geo.hats:
                if abs(hx - c.x) + abs(hy - c.y) > 2 * (C.HAT_RADIUS + move):
                    continue
                if c.vx * fx + c.vy * fy >= 0.0:
                    continue  # moving away from (or along) the opening
                if _point_segment_distance((hx, hy), p, q) >= C.HAT_RADIUS:
                    continue
                speed = math.hypot(c.vx, c.vy) * C.HAT_SPEED_FACTOR
                gap = C.HAT_RADIUS + r + C.HAT_EXIT_GAP
                c.x, c.y = ox + gx * gap, oy + gy * gap
                c.vx, c.vy = speed * gx, speed * gy
                snapped = [rope for rope in self.ropes if rope.candy == i]
                for rope in snapped:
                    self._drop_rope(rope)
                self._event(f"{what} went through magic hat pair {pair + 1}" + (" (its ropes snapped)" if snapped else ""))
                p = q = (c.x, c.y)
                changed = True
                break
            # active pins
            for k, a in enumerate(self.active_pins):
                if a.state == "armed" and (c.x - a.x) ** 2 + (c.y - a.y) ** 2 <= (a.radius + C.ACTIVE_PIN_MARGIN) ** 2:
                    a.state = "attached"
                    self.ropes.append(Rope("active", k + 1, a.x, a.y, math.hypot(c.x - a.x, c.y - a.y), i))
                    changed = True
                    self._event(f"active pin A{k + 1} attached a rope to {what}")
            # Om Nom
            ox, oy = geo.om_nom
            reach = C.OMNOM_RADIUS + r
            d = math.hypot(ox - c.x, oy - c.y)
            if not c.half and d < self.min_mouth_distance:
                self.min_mouth_distance = d
            if d < reach + move and _point_segment_distance((ox, oy), p, q) < reach:
                c.alive = False
                if c.half:
                    self._lose("Om Nom ate a candy half: he needs the whole candy")
                else:
                    self.status, self.reason = "won", "Om Nom ate the candy"
                    self._event(self.reason)
                return True

        for s in self.spiders:  # spiders crawl toward the candy
            if s.gone or t < seconds_to_steps(s.delay):
                continue
            rope = self.rope_of_pin(s.pin)
            if rope is None:
                s.gone = True
                continue
            s.crawled += C.SPIDER_SPEED * C.DT
            if s.crawled >= self.rope_span(rope):
                taken = self.candies[rope.candy]
                taken.alive = False
                self._lose(f"the spider on the rope of P{s.pin} reached {_named(taken)} and took it")
                return True

        if level.halves:
            halves = [i for i, c in enumerate(self.candies) if c.alive and c.half]
            if len(halves) == 2:  # the halves join
                a, b = (self.candies[i] for i in halves)
                gap = math.hypot(a.x - b.x, a.y - b.y) - a.radius - b.radius
                self.min_join_gap = min(self.min_join_gap, gap)
                if gap < 0.0:
                    self._join(*halves)
                    changed = True
        return changed

    def _drop_rope(self, rope: Rope) -> None:
        self.ropes.remove(rope)
        if rope.source == "active":
            self.active_pins[rope.sid - 1].state = "cut"
        for s in self.spiders:
            if rope.source == "pin" and s.pin == rope.sid:
                s.gone = True

    def _join(self, i: int, j: int) -> None:
        a, b = self.candies[i], self.candies[j]
        m = a.mass + b.mass
        whole = Candy(x=(a.x * a.mass + b.x * b.mass) / m, y=(a.y * a.mass + b.y * b.mass) / m,
                      vx=(a.vx * a.mass + b.vx * b.mass) / m, vy=(a.vy * a.mass + b.vy * b.mass) / m)
        a.alive = b.alive = False
        self.candies.append(whole)
        k = len(self.candies) - 1
        for r in self.ropes:
            if r.candy in (i, j):
                r.candy = k
                r.length = max(r.length, math.hypot(whole.x - r.ax, whole.y - r.ay))
        carrying = [bb for bb in self.bubbles if not bb.popped and bb.candy in (i, j)]
        for n, bb in enumerate(carrying):
            if n == 0:
                bb.candy = k
            else:  # one bubble carries the joined candy; the other bursts
                bb.popped, bb.candy = True, None
        self._event("the two halves joined into one candy")

    def sync_bubbles(self) -> None:
        """Bubbles carrying a candy sit on it (for drawing and the text)."""
        for b in self.bubbles:
            if b.candy is not None and not b.popped:
                c = self.candies[b.candy]
                b.x, b.y = c.x, c.y


CANDIES = pymunk.ShapeFilter(group=1)  # candies do not collide with each other


def _named(candy: Candy) -> str:
    """The candy in the feedback's words: two halves that joined are "the candy" again."""
    return "a candy half" if candy.half else "the candy"


def _add_body(space: pymunk.Space, candy: Candy) -> pymunk.Body:
    """A candy's body: a solid disc of its mass (ropes pull at its centre; it rolls on
    walls), whose circle collides with walls."""
    body = pymunk.Body(candy.mass, pymunk.moment_for_circle(candy.mass, 0.0, candy.radius))
    body.position = (candy.x, candy.y)
    body.velocity = (candy.vx, candy.vy)
    body.angular_velocity = candy.spin
    shape = pymunk.Circle(body, candy.radius)
    shape.elasticity, shape.friction, shape.filter = C.CANDY_ELASTICITY, C.CANDY_FRICTION, CANDIES
    space.add(body, shape)
    return body


def _buoyant(body: pymunk.Body, gravity, damping: float, dt: float) -> None:
    """Velocity update inside a bubble: gravity replaced by a lift, with drag, so the
    velocity relaxes to BUBBLE_RISE_SPEED upward (ropes still pull through the body's force)."""
    lift = -C.BUBBLE_DRAG * C.BUBBLE_RISE_SPEED
    pymunk.Body.update_velocity(body, (0.0, lift), math.exp(-C.BUBBLE_DRAG * dt), dt)


def _pull(dx: float, dy: float, vx: float, vy: float, length: float) -> tuple[float, float, float]:
    """A rope's pull on its candy, (tension, unit vector from the pin to the candy), given the
    candy's offset and velocity relative to the pin: a damped spring on the stretch beyond the
    rest length, never pushing."""
    d = math.hypot(dx, dy)
    if d <= length:
        return 0.0, 0.0, 0.0
    ux, uy = dx / d, dy / d
    tension = ROPE_K * (d - length) + ROPE_C * (vx * ux + vy * uy)
    return (tension, ux, uy) if tension > 0.0 else (0.0, 0.0, 0.0)


def _point_segment_distance(p, a, b) -> float:
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    px, py = p[0] - ax, p[1] - ay
    n = dx * dx + dy * dy
    t = 0.0 if n == 0.0 else max(0.0, min(1.0, (px * dx + py * dy) / n))
    return math.hypot(px - t * dx, py - t * dy)


def _segment_distance(p, q, a, b) -> float:
    """Distance between segments pq and ab."""
    if _segments_cross(p, q, a, b):
        return 0.0
    return min(_point_segment_distance(p, a, b), _point_segment_distance(q, a, b),
               _point_segment_distance(a, p, q), _point_segment_distance(b, p, q))


def _segments_cross(p, q, a, b) -> bool:
    def orient(o, u, v):
        return (u[0] - o[0]) * (v[1] - o[1]) - (u[1] - o[1]) * (v[0] - o[0])

    d1, d2 = orient(a, b, p), orient(a, b, q)
    d3, d4 = orient(p, q, a), orient(p, q, b)
    return ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and d1 != 0 and d2 != 0 and d3 != 0 and d4 != 0
