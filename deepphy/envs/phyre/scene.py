"""PHYRE scenes on pymunk: objects, simulation with the success rule, rendering.

Conventions follow the original PHYRE (facebookresearch/phyre):
- the scene is 256 x 256 px, x to the right, y UP (images are flipped when drawn);
- gravity is -9.8 m/s^2 at 6 px per metre (-58.8 px/s^2), 60 steps per second, at most
  1000 steps (~16.7 s); density, friction (0.5) and restitution (0.2) are the same for
  every object, as in PHYRE's Box2D conversion;
- four invisible static walls enclose the scene (a wall can be a goal object, then it is
  drawn as a purple strip along that edge);
- colours: black = static, gray = dynamic, green = the dynamic subject of the goal,
  blue = a dynamic goal object, purple = a static goal object, red = the placed ball;
- bars are 256/50 px thick; jars are open-top trapezoids with a flat base.

Success rule (PHYRE's `simulateTask`): TOUCHING holds when the green object touches any
goal object; it must hold for 180 consecutive steps (3 s). NOT_TOUCHING (template 19):
solved when the two never touch during the whole simulation, or, after touching, stay
apart for 180 consecutive steps.

An episode stops early once its outcome is decided: success held long enough, or every
dynamic body is at rest (then nothing can change any more: the current relation decides).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, Sequence

import cv2
import numpy as np
import pymunk

W = H = 256.0  # scene size in px
GRAVITY = -9.8 * 6.0  # px / s^2 (PHYRE: -9.8 m/s^2, 6 px per metre)
FPS = 60
DT = 1.0 / FPS
MAX_STEPS = 1000
SOLVE_STEPS = 180  # 3 s of the goal relation
BAR_T = W / 50.0  # PHYRE bar thickness (5.12 px)
FRICTION = 0.5
ELASTICITY = 0.2
DENSITY = 0.25
WALL_T = 20.0
ITERATIONS = 10
# Rest detection: every REST_CHECK steps; at rest when every dynamic body moved less than
# REST_SPEED px/s and REST_SPIN rad/s for REST_CHECKS consecutive checks.
REST_CHECK = 10
REST_CHECKS = 4
REST_SPEED = 0.5
REST_SPIN = 0.02
EXPLODE_SPEED = 2000.0  # px/s: anything faster is a broken scene (tests use it)

Color = Literal["black", "gray", "green", "blue", "purple", "red"]
COLORS: dict[str, tuple[int, int, int]] = {  # RGB, close to PHYRE's palette
    "black": (0, 0, 0),
    "gray": (176, 176, 176),
    "green": (33, 180, 63),
    "blue": (48, 104, 224),
    "purple": (160, 64, 200),
    "red": (232, 64, 48),
}
WALLS = ("bottom", "left", "right", "top")


@dataclass(frozen=True)
class Obj:
    """One rigid body: a pose and convex parts in body coordinates.

    `parts` holds circles ("circle", radius) and convex polygons ("poly", vertices).
    Build objects with `ball`, `bar`, `box`, `jar`, `poly` rather than by hand.
    """

    kind: str  # ball | bar | box | jar | poly (for descriptions)
    x: float
    y: float
    angle: float  # radians, counter-clockwise
    dynamic: bool
    color: Color
    parts: tuple  # (("circle", r),) or (("poly", ((x, y), ...)), ...)
    size: tuple = ()  # kind-specific sizes, for descriptions

    @property
    def is_ball(self) -> bool:
        return self.kind == "ball"


def _check_color(color: str, dynamic: bool) -> None:
    if color in ("black", "purple") and dynamic:
        raise ValueError(f"{color} objects are static")
    if color in ("gray", "green", "blue", "red") and not dynamic:
        raise ValueError(f"{color} objects are dynamic")


def ball(x: float, y: float, r: float, color: Color = "gray") -> Obj:
    dynamic = color not in ("black", "purple")
    return Obj("ball", x, y, 0.0, dynamic, color, (("circle", float(r)),), (float(r),))


def box(x: float, y: float, w: float, h: float, angle: float = 0.0, color: Color = "black") -> Obj:
    """A w x h rectangle centred at (x, y), rotated by `angle` radians."""
    dynamic = color not in ("black", "purple")
    v = ((-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2))
    return Obj("box", x, y, angle, dynamic, color, (("poly", v),), (w, h))


def bar(x: float, y: float, length: float, angle: float = 0.0, color: Color = "black", thickness: float = BAR_T) -> Obj:
    """A bar of `length` centred at (x, y); angle in radians (0 = horizontal)."""
    o = box(x, y, length, thickness, angle, color)
    return Obj("bar", o.x, o.y, o.angle, o.dynamic, o.color, o.parts, (length, thickness))


def bar_between(x0: float, y0: float, x1: float, y1: float, color: Color = "black", thickness: float = BAR_T) -> Obj:
    """A bar whose centre line runs from (x0, y0) to (x1, y1)."""
    return bar((x0 + x1) / 2, (y0 + y1) / 2, math.hypot(x1 - x0, y1 - y0), math.atan2(y1 - y0, x1 - x0), color, thickness)


def jar(x: float, bottom: float, width: float, height: float, color: Color = "gray", angle: float = 0.0,
        thickness: float | None = None, base_ratio: float = 0.8) -> Obj:
    """An open jar (PHYRE's shape): flat base, slanted walls, mouth `width` wide at the top.

    (x, bottom) is the middle of the underside of the base; the body origin is there.
    """
    t = thickness if thickness is not None else max(2.5, BAR_T * math.log(max(height, 2.0)) / math.log(0.3 * W))
    bw = width * base_ratio
    base = ((-bw / 2, 0.0), (bw / 2, 0.0), (bw / 2, t), (-bw / 2, t))
    left = ((-bw / 2, 0.0), (-bw / 2 + t, 0.0), (-width / 2 + t, height), (-width / 2, height))
    right = ((bw / 2 - t, 0.0), (bw / 2, 0.0), (width / 2, height), (width / 2 - t, height))
    dynamic = color not in ("black", "purple")
    return Obj("jar", x, bottom, angle, dynamic, color, (("poly", base), ("poly", left), ("poly", right)),
               (width, height, t))


def poly(points: Sequence[tuple[float, float]], color: Color = "black") -> Obj:
    """A convex polygon given in scene coordinates (counter-clockwise), e.g. a ramp wedge."""
    cx = sum(p[0] for p in points) / len(points)
    cy = sum(p[1] for p in points) / len(points)
    v = tuple((p[0] - cx, p[1] - cy) for p in points)
    dynamic = color not in ("black", "purple")
    return Obj("poly", cx, cy, 0.0, dynamic, color, (("poly", v),))


@dataclass(frozen=True)
class Scene:
    """A task's initial scene and goal.

    `subject` is the index of the green object; `goal` lists the goal objects: indices
    into `objects` and/or wall names ("bottom", "left", "right", "top"). The relation is
    "touching" (any of them) or "not_touching" (none of them).
    """

    objects: tuple[Obj, ...]
    subject: int
    goal: tuple  # of int | str
    relation: Literal["touching", "not_touching"] = "touching"
    description: str = ""

    def __post_init__(self) -> None:
        for o in self.objects:
            _check_color(o.color, o.dynamic)
            for kind, data in o.parts:
                if kind == "circle" and not data >= 1.0:
                    raise ValueError(f"ball radius {data} is too small")
        if self.objects[self.subject].color != "green":
            raise ValueError("the subject must be the green object")
        for g in self.goal:
            if isinstance(g, str):
                if g not in WALLS:
                    raise ValueError(f"unknown wall {g!r}")
            elif self.objects[g].color not in ("blue", "purple"):
                raise ValueError("goal objects are blue (dynamic) or purple (static)")


# -- geometry helpers -------------------------------------------------------------------


def world_points(o: Obj, verts) -> list[tuple[float, float]]:
    c, s = math.cos(o.angle), math.sin(o.angle)
    return [(o.x + c * vx - s * vy, o.y + s * vx + c * vy) for vx, vy in verts]


def bounds(o: Obj) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) of an object in the scene."""
    xs, ys = [], []
    for kind, data in o.parts:
        if kind == "circle":
            xs += [o.x - data, o.x + data]
            ys += [o.y - data, o.y + data]
        else:
            for px, py in world_points(o, data):
                xs.append(px)
                ys.append(py)
    return min(xs), min(ys), max(xs), max(ys)


def inside_scene(o: Obj, margin: float = 0.0) -> bool:
    x0, y0, x1, y1 = bounds(o)
    return x0 >= margin and y0 >= margin and x1 <= W - margin and y1 <= H - margin


# -- simulation -------------------------------------------------------------------------

SUBJECT, GOAL, OTHER = 1, 2, 0


@dataclass
class Outcome:
    success: bool
    steps: int  # steps simulated
    reason: str  # "solved", "at_rest", "time_out", "touched"...
    touched_ever: bool
    max_speed: float = 0.0
    left_scene: bool = False
    snapshots: list = field(default_factory=list)  # [(step, [(x, y, angle) per body])]


class World:
    """A pymunk space built from a scene (plus an optional placed red ball)."""

    def __init__(self, scene: Scene, action_ball: Obj | None = None) -> None:
        self.scene = scene
        self.space = space = pymunk.Space()
        space.gravity = (0.0, GRAVITY)
        space.iterations = ITERATIONS
        self.objects = list(scene.objects) + ([action_ball] if action_ball is not None else [])
        self.bodies: list[pymunk.Body] = []
        self.dynamic: list[pymunk.Body] = []
        goal_idx = {g for g in scene.goal if isinstance(g, int)}
        for i, o in enumerate(self.objects):
            body = pymunk.Body(body_type=pymunk.Body.DYNAMIC if o.dynamic else pymunk.Body.STATIC)
            shapes = []
            for kind, data in o.parts:
                if kind == "circle":
                    shape = pymunk.Circle(body, data)
                else:
                    shape = pymunk.Poly(body, data)
                shape.friction = FRICTION
                shape.elasticity = ELASTICITY
                if o.dynamic:
                    shape.density = DENSITY
                shape.collision_type = SUBJECT if i == scene.subject else GOAL if i in goal_idx else OTHER
                shapes.append(shape)
            body.position = (o.x, o.y)
            body.angle = o.angle
            space.add(body, *shapes)
            self.bodies.append(body)
            if o.dynamic:
                self.dynamic.append(body)
        for name in WALLS:
            body = pymunk.Body(body_type=pymunk.Body.STATIC)
            x0, y0, x1, y1 = {
                "bottom": (-WALL_T, -WALL_T, W + WALL_T, 0.0),
                "top": (-WALL_T, H, W + WALL_T, H + WALL_T),
                "left": (-WALL_T, -WALL_T, 0.0, H + WALL_T),
                "right": (W, -WALL_T, W + WALL_T, H + WALL_T),
            }[name]
            shape = pymunk.Poly(body, ((x0, y0), (x1, y0), (x1, y1), (x0, y1)))
            shape.friction = FRICTION
            shape.elasticity = ELASTICITY
            shape.collision_type = GOAL if name in scene.goal else OTHER
            space.add(body, shape)
        self.contacts = 0
        handler = space.add_collision_handler(SUBJECT, GOAL)
        handler.begin = self._begin
        handler.separate = self._separate

    def _begin(self, arbiter, space, data) -> bool:
        self.contacts += 1
        return True

    def _separate(self, arbiter, space, data) -> None:
        self.contacts -= 1

    @property
    def touching(self) -> bool:
        return self.contacts > 0

    def state(self) -> list[tuple[float, float, float]]:
        return [(b.position.x, b.position.y, b.angle) for b in self.bodies]

    def run(self, max_steps: int = MAX_STEPS, snapshot_every: int = 0, early_stop: bool = True) -> Outcome:
        """Simulate with PHYRE's success rule; stop early once the outcome is decided."""
        not_touching = self.scene.relation == "not_touching"
        holds = lambda: self.touching != not_touching  # noqa: E731
        # NOT_TOUCHING that holds from the start counts as solved only if it never breaks.
        looking = not (not_touching and holds())
        count = 0
        touched_ever = False
        rest_checks = 0
        max_speed = 0.0
        snapshots = [(0, self.state())] if snapshot_every else []
        step = 0
        success = False
        reason = "time_out"
        dyn = self.dynamic
        while step < max_steps:
            self.space.step(DT)
            step += 1
            if self.touching:
                touched_ever = True
            if holds():
                count += 1
                if looking and count >= SOLVE_STEPS:
                    success, reason = True, "solved"
                    break
            else:
                looking = True
                count = 0
            if snapshot_every and step % snapshot_every == 0:
                snapshots.append((step, self.state()))
            if step % REST_CHECK == 0:
                speed = max((b.velocity.length for b in dyn), default=0.0)
                spin = max((abs(b.angular_velocity) for b in dyn), default=0.0)
                max_speed = max(max_speed, speed)
                if not speed <= EXPLODE_SPEED:  # also NaN
                    reason = "exploded"
                    break
                rest_checks = rest_checks + 1 if speed < REST_SPEED and spin < REST_SPIN else 0
                if early_stop and rest_checks >= REST_CHECKS:
                    # Nothing moves any more: the current relation stays as it is.
                    reason = "at_rest"
                    success = holds()
                    break
        else:
            if not looking and count == step:
                success, reason = True, "solved"  # NOT_TOUCHING held the whole time
        if snapshot_every and (not snapshots or snapshots[-1][0] != step):
            snapshots.append((step, self.state()))
        left = any(not (-5 <= b.position.x <= W + 5 and -5 <= b.position.y <= H + 5) for b in dyn)
        return Outcome(success, step, reason, touched_ever, max_speed, left, snapshots)


def placement_problem(scene: Scene, x: float, y: float, r: float) -> str | None:
    """Why a red ball at (x, y) with radius r cannot be placed, or None if it can."""
    if x - r < 0 or x + r > W or y - r < 0 or y + r > H:
        return f"the ball (x={x:.1f}, y={y:.1f}, radius={r:.1f} px) does not fit inside the scene"
    probe = pymunk.Circle(pymunk.Body(body_type=pymunk.Body.KINEMATIC), r)
    probe.body.position = (x, y)
    probe.cache_bb()
    for i, o in enumerate(scene.objects):
        x0, y0, x1, y1 = bounds(o)
        if x + r < x0 or x - r > x1 or y + r < y0 or y - r > y1:
            continue
        body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        body.position = (o.x, o.y)
        body.angle = o.angle
        for kind, data in o.parts:
            shape = pymunk.Circle(body, data) if kind == "circle" else pymunk.Poly(body, data)
            shape.cache_bb()
            pts = probe.shapes_collide(shape).points
            if pts and min(p.distance for p in pts) < -0.01:
                return f"the ball overlaps the {o.color} {o.kind} at ({o.x:.0f}, {o.y:.0f})"
    return None


def simulate(scene: Scene, action: tuple[float, float, float] | None = None, *, snapshot_every: int = 0,
             max_steps: int = MAX_STEPS) -> Outcome:
    """Run a scene with an optional red ball (x, y, r) in px. The placement must be valid."""
    extra = ball(action[0], action[1], action[2], "red") if action is not None else None
    return World(scene, extra).run(max_steps=max_steps, snapshot_every=snapshot_every)


# -- rendering --------------------------------------------------------------------------


def render(objects: Sequence[Obj], state: Sequence[tuple[float, float, float]] | None = None,
           goal_walls: Sequence[str] = (), size: int = 512) -> np.ndarray:
    """RGB image (size x size) of the objects, at their initial poses or at `state`."""
    s = size / W
    img = np.full((size, size, 3), 255, np.uint8)
    shift = 4  # sub-pixel precision for cv2
    mul = s * (1 << shift)

    def pt(px: float, py: float) -> tuple[int, int]:
        return int(round(px * mul)), int(round((H - py) * mul))

    # Static first, then dynamic, so moving things stay visible.
    order = sorted(range(len(objects)), key=lambda i: (objects[i].dynamic, objects[i].color == "red"))
    for i in order:
        o = objects[i]
        x, y, a = state[i] if state is not None else (o.x, o.y, o.angle)
        c, sn = math.cos(a), math.sin(a)
        color = COLORS[o.color]
        for kind, data in o.parts:
            if kind == "circle":
                cv2.circle(img, pt(x, y), int(round(data * mul)), color, -1, cv2.LINE_AA, shift)
                if o.dynamic and data * s > 6:  # a spoke shows rotation
                    e = (x + c * data * 0.8, y + sn * data * 0.8)
                    shade = tuple(int(v * 0.6) for v in color)
                    cv2.line(img, pt(x, y), pt(*e), shade, max(1, int(s)), cv2.LINE_AA, shift)
            else:
                pts = np.array([pt(x + c * vx - sn * vy, y + sn * vx + c * vy) for vx, vy in data], np.int32)
                cv2.fillPoly(img, [pts], color, cv2.LINE_AA, shift)
    band = max(3, int(round(3 * s)))
    purple = COLORS["purple"]
    for wall in goal_walls:
        if wall == "bottom":
            img[size - band :, :] = purple
        elif wall == "top":
            img[:band, :] = purple
        elif wall == "left":
            img[:, :band] = purple
        elif wall == "right":
            img[:, size - band :] = purple
    return img
