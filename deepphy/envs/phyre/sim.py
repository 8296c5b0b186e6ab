"""PHYRE's simulation on Box2D: the task's bodies plus one placed ball, PHYRE's rules.

Reproduces phyre 0.2.2 (`src/simulator/`: thrift_box2d_conversion, task_utils
`simulateTask`, task_validation `isTaskInSolvedState`, image_to_box2d
`mergeUserInputIntoScene`; `src/python/phyre/action_mappers.py`):
- scene 256 x 256 px, y up, 6 px per metre; gravity -9.8 m/s^2; dt 1/60 s; 15 velocity and
  20 position iterations; friction 0.5 and restitution 0.2 for every shape, density 0.25
  for dynamic bodies; angular damping 0.01, linear 0; at most 1000 steps. Bodies are
  created in the task's order, then the ball; px -> m in float32 as PHYRE's C++ does.
- Goal: `body1` TOUCHING `body2` (a touching Box2D contact between them; contacts with
  the placed ball never count) for 180 consecutive steps. When both goal bodies are single
  circles the test is PHYRE's: centre distance < r1 + r2 + 0.1 px (float32).
- Action (x, y, r) in [0, 1]^3 -> the ball in px: `space.ball_from_action`. Invalid if
  the ball overlaps any body (touching allowed, 1e-5 px), with PHYRE's float32 geometry.
- The simulation stops early only where the outcome is certain: the goal held 180 steps
  (PHYRE stops there too); every dynamic body asleep (Box2D then changes nothing more,
  so the remaining steps are known); or too few steps left to reach 180.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import Box2D as B
import numpy as np

from deepphy.envs.phyre.data import PhyreTask
from deepphy.envs.phyre.space import Ball, InvalidPlacement, ball_from_action

PIXELS_PER_METRE = 6.0
GRAVITY = -9.8  # m/s^2
FPS = 60
VELOCITY_ITERATIONS = 15
POSITION_ITERATIONS = 20
FRICTION = 0.5
RESTITUTION = 0.2
DENSITY = 0.25
ANGULAR_DAMPING = 0.01
MAX_STEPS = 1000
SOLVED_STEPS = 3 * FPS  # the goal must hold this many consecutive steps
BALL_TOUCH_PX = 0.1  # two goal balls touch when their gap is below this
INSIDENESS_EPS = 1e-5  # px: overlaps smaller than this are touching, not occluding

_f32 = np.float32
_PPM = _f32(PIXELS_PER_METRE)
_DT = float(_f32(1.0) / _f32(FPS))  # PHYRE: 1.0f / 60
_BALL_TOUCH_M = _f32(BALL_TOUCH_PX / PIXELS_PER_METRE)
_EPS = _f32(INSIDENESS_EPS)
REST_CHECK_EVERY = 10  # steps between checks for "every body asleep" (a later check is as exact)
USER = -1  # userData of the placed ball; scene bodies carry their index

Poses = list[tuple[float, float, float]]  # (x px, y px, angle rad) per dynamic body


@dataclass
class Outcome:
    solved: bool
    steps: int  # steps PHYRE simulates: up to the step the goal completes, else MAX_STEPS
    simulated: int  # steps actually computed (fewer when the outcome was already certain)
    end: str  # "solved" | "at_rest" | "time_out"
    touched: bool  # the goal relation held at some computed step
    frames: list[tuple[int, Poses]] = field(default_factory=list)  # (step, poses)


def check_placement(task: PhyreTask, ball: Ball) -> None:
    """Raise InvalidPlacement if the ball overlaps a body of the scene (PHYRE's check)."""
    for body in task.bodies:
        if _occludes(ball, body):
            what = "wall" if body.kind == "undefined" else f"{body.color} {body.kind}"  # PHYRE's 4 walls
            raise InvalidPlacement(f"the ball overlaps the {what} at ({body.x:.0f}, {body.y:.0f})")


def place(task: PhyreTask, ax: float, ay: float, ar: float) -> Ball:
    """The valid ball for action (x, y, r) in [0, 1]^3, or InvalidPlacement."""
    ball = ball_from_action(ax, ay, ar)
    check_placement(task, ball)
    return ball


def simulate(task: PhyreTask, ball: Ball | None, *, frame_every: int = 0, early_stop: bool = True) -> Outcome:
    """Run the task with the ball (already checked) under PHYRE's rules.

    `frame_every` > 0 records the dynamic bodies' poses at step 0, every `frame_every`
    steps and at the last step computed. `early_stop=False` computes every step PHYRE
    does (the reference the early stops are tested against).
    """
    world, bodies, dynamic = _build_world(task, ball)
    body1, body2 = bodies[task.body1], bodies[task.body2]
    holds = _goal_test(task, body1, body2)
    count = 0
    touched = False
    frames = [(0, _poses(dynamic))] if frame_every else []
    step, solved, end = 0, False, "time_out"
    advance = world.Step
    while step < MAX_STEPS:
        advance(_DT, VELOCITY_ITERATIONS, POSITION_ITERATIONS)
        step += 1
        if holds():
            count += 1
            touched = True
            if count >= SOLVED_STEPS:
                solved, end = True, "solved"
                break
        else:
            count = 0
        if frame_every and step % frame_every == 0:
            frames.append((step, _poses(dynamic)))
        if not early_stop:
            continue
        if count + MAX_STEPS - step < SOLVED_STEPS:
            break  # cannot hold long enough any more
        if step % REST_CHECK_EVERY == 0 and not any(b.awake for b in dynamic):
            # Nothing moves or wakes again: the relation keeps its present value.
            end = "at_rest"
            if count and count + MAX_STEPS - step >= SOLVED_STEPS:
                solved = True
            break
    if frame_every and frames[-1][0] != step:
        frames.append((step, _poses(dynamic)))
    if not solved:
        steps = MAX_STEPS
    else:  # at rest, the goal completes SOLVED_STEPS - count steps later
        steps = step if end == "solved" else step + SOLVED_STEPS - count
    return Outcome(solved=solved, steps=steps, simulated=step, end=end, touched=touched, frames=frames)


# -- Box2D ----------------------------------------------------------------------------------


def _m(px: float) -> float:
    """PHYRE's p2m: px (a double, passed as float) / 6 in float32."""
    return float(_f32(px) / _PPM)


def _build_world(task: PhyreTask, ball: Ball | None):
    world = B.b2World(gravity=(0.0, GRAVITY), doSleep=True)
    bodies, dynamic = [], []
    for i, b in enumerate(task.bodies):
        body = _add_body(world, b.x, b.y, b.angle, b.dynamic, i)
        for s in b.shapes:
            if s.polygon is not None:
                shape = B.b2PolygonShape(vertices=[(_m(vx), _m(vy)) for vx, vy in s.polygon])
            else:
                shape = B.b2CircleShape(radius=_m(s.radius))
            _add_fixture(body, shape, b.dynamic)
        bodies.append(body)
        if b.dynamic:
            dynamic.append(body)
    if ball is not None:
        body = _add_body(world, ball.x, ball.y, 0.0, True, USER)
        _add_fixture(body, B.b2CircleShape(radius=_m(ball.r)), True)
        dynamic.append(body)
    return world, bodies, dynamic


def _add_body(world, x: float, y: float, angle: float, dynamic: bool, tag: int):
    d = B.b2BodyDef()
    d.position = (_m(x), _m(y))
    d.angle = angle
    d.angularDamping = ANGULAR_DAMPING
    d.linearDamping = 0.0
    if dynamic:
        d.type = B.b2_dynamicBody
    body = world.CreateBody(d)
    body.userData = tag  # pybox2d wraps bodies anew on each access: identify them by tag
    return body


def _add_fixture(body, shape, dynamic: bool) -> None:
    body.CreateFixture(B.b2FixtureDef(shape=shape, friction=FRICTION, restitution=RESTITUTION,
                                      density=DENSITY if dynamic else 0.0))


def _goal_test(task: PhyreTask, body1, body2):
    """A function of the world's present state: does the goal relation hold?"""
    s1, s2 = task.bodies[task.body1].shapes, task.bodies[task.body2].shapes
    if len(s1) == 1 and len(s2) == 1 and s1[0].radius is not None and s2[0].radius is not None:
        limit = _f32(body1.fixtures[0].shape.radius) + _f32(body2.fixtures[0].shape.radius) + _BALL_TOUCH_M
        limit64 = float(limit)
        near = limit64 * 1e-5  # float32 rounding moves the distance by far less than this

        def balls_touch() -> bool:
            p, q = body1.position, body2.position
            dx, dy = p[0] - q[0], p[1] - q[1]
            gap = math.sqrt(dx * dx + dy * dy) - limit64
            if abs(gap) > near:
                return gap < 0
            fx, fy = _f32(p[0]) - _f32(q[0]), _f32(p[1]) - _f32(q[1])  # PHYRE's float32 arithmetic
            return bool(np.sqrt(fx * fx + fy * fy) < limit)

        return balls_touch

    other = task.body2

    def touching() -> bool:
        for edge in body1.contacts:
            if edge.other.userData == other and edge.contact.touching:
                return True
        return False

    return touching


def _poses(dynamic) -> Poses:
    out = []
    for b in dynamic:
        p = b.position
        out.append((p[0] * PIXELS_PER_METRE, p[1] * PIXELS_PER_METRE, b.angle))
    return out


# -- PHYRE's occlusion test (geometry.h, float32 where PHYRE uses float) ----------------------


def _occludes(ball: Ball, body) -> bool:
    for s in body.shapes:
        if s.radius is not None:
            # isPointInsideCircle(ball centre, body centre, r_ball + r_shape)
            if _dist(ball.x - body.x, ball.y - body.y) + _EPS < _f32(ball.r + s.radius):
                return True
        else:
            # the ball centre in the body frame: rotate(p - position, -angle), cos/sin in float
            angle = float(_f32(-body.angle))
            c, sn = float(_f32(math.cos(angle))), float(_f32(math.sin(angle)))
            dx, dy = ball.x - body.x, ball.y - body.y
            px, py = dx * c - dy * sn, dx * sn + dy * c
            if _inside_polygon(s.polygon, px, py):
                return True
            if np.sqrt(_square_distance_to_polygon(s.polygon, px, py)) + _EPS < _f32(ball.r):
                return True
    return False


def _dist(dx: float, dy: float):
    fx, fy = _f32(dx), _f32(dy)
    return np.sqrt(fx * fx + fy * fy)


def _square_distance(ax: float, ay: float, bx: float, by: float):
    dx, dy = _f32(ax - bx), _f32(ay - by)
    return dx * dx + dy * dy


def _inside_polygon(poly, px: float, py: float) -> bool:
    """Strictly inside (geometry::isInsidePolygon)."""
    n = len(poly)
    for i in range(n):
        (jx, jy), (ix, iy) = poly[i - 1], poly[i]
        if _f32((ix - jx) * (py - jy) - (iy - jy) * (px - jx)) <= 0:
            return False
    return True


def _square_distance_to_segment(lx, ly, rx, ry, px, py):
    ex, ey = rx - lx, ry - ly
    projection = _f32(ex * (px - lx) + ey * (py - ly))
    edge = _square_distance(lx, ly, rx, ry)
    if projection < 0 or edge < _f32(1e-4):
        return _square_distance(lx, ly, px, py)
    if projection > edge:
        return _square_distance(rx, ry, px, py)
    num = _f32(ey * px - ex * py + rx * ly - ry * lx)
    return num * num / edge


def _square_distance_to_polygon(poly, px: float, py: float):
    (lx, ly), (rx, ry) = poly[-1], poly[0]
    best = _square_distance_to_segment(lx, ly, rx, ry, px, py)
    for (lx, ly), (rx, ry) in zip(poly, poly[1:]):
        best = min(best, _square_distance_to_segment(lx, ly, rx, ry, px, py))
    return best

