"""The side view a model sees, drawn with OpenCV: sky, ground, slingshot, the birds waiting,
blocks coloured by material (darker, with cracks, as they take damage), pigs, TNT, the
trail of the last shot. No labels: the text observation names what the picture shows."""

from __future__ import annotations

import functools
import math
from typing import Sequence

import cv2
import numpy as np

from deepphy.envs.angrybirds import constants as C
from deepphy.envs.angrybirds.levels import Level
from deepphy.envs.angrybirds.sim import Pose

WIDTH, HEIGHT = 960, 540
SCALE = WIDTH / C.WORLD_W  # pixels per world unit (48)
_SHIFT = 4  # sub-pixel precision of OpenCV's polygon drawing
_F = 1 << _SHIFT

# Colours (RGB); the prompt's legend names them.
SKY_TOP, SKY_BOTTOM = (110, 170, 230), (200, 230, 250)
GRASS, DIRT = (90, 170, 60), (150, 110, 70)
PLATFORM, PLATFORM_EDGE = (110, 95, 85), (60, 50, 45)
MATERIAL_FILL = {"wood": (205, 150, 85), "ice": (175, 225, 245), "stone": (150, 150, 158)}
MATERIAL_EDGE = {"wood": (120, 80, 40), "ice": (90, 150, 190), "stone": (80, 80, 88)}
PIG_FILL, PIG_EDGE, PIG_SNOUT = (120, 200, 70), (50, 110, 30), (160, 225, 110)
TNT_FILL, TNT_EDGE, TNT_TEXT = (200, 70, 40), (110, 30, 15), (250, 220, 80)
BIRD_FILL = {"red": (215, 40, 40), "yellow": (245, 210, 40), "blue": (80, 150, 230), "black": (35, 35, 40)}
BEAK = (245, 160, 30)
SLING, SLING_DARK = (120, 75, 35), (80, 45, 20)
TRAIL, TRAIL_EDGE = (255, 255, 255), (90, 90, 90)
BLAST = (255, 170, 40)
CRACK = (40, 30, 25)


def to_px(x: float, y: float) -> tuple[float, float]:
    return x * SCALE, HEIGHT - (y - (C.GROUND_Y - C.GROUND_DEPTH)) * SCALE


def _pts(points: Sequence[tuple[float, float]]) -> np.ndarray:
    return np.array([[round(px * _F), round(py * _F)] for px, py in (to_px(x, y) for x, y in points)], np.int32)


def _circle(img: np.ndarray, x: float, y: float, r: float, fill, edge=None, thickness: int = 1) -> None:
    cx, cy = to_px(x, y)
    c, rad = (round(cx * _F), round(cy * _F)), max(1, round(r * SCALE * _F))
    cv2.circle(img, c, rad, fill, -1, cv2.LINE_AA, _SHIFT)
    if edge is not None:
        cv2.circle(img, c, rad, edge, thickness, cv2.LINE_AA, _SHIFT)


def _shade(colour: tuple[int, int, int], damage: float) -> tuple[int, int, int]:
    k = 1.0 - 0.45 * damage
    return tuple(int(c * k) for c in colour)  # type: ignore[return-value]


@functools.lru_cache(maxsize=1)
def _background() -> np.ndarray:
    img = np.zeros((HEIGHT, WIDTH, 3), np.uint8)
    ground_px = int(round(to_px(0, C.GROUND_Y)[1]))
    t = np.linspace(0.0, 1.0, ground_px)[:, None]
    img[:ground_px] = (np.array(SKY_TOP) * (1 - t) + np.array(SKY_BOTTOM) * t).astype(np.uint8)[:, None, :]
    img[ground_px:] = DIRT
    img[ground_px : ground_px + 7] = GRASS
    # The slingshot's trunk (the arms are drawn around the bird).
    bx, by = to_px(C.SLING_X, C.GROUND_Y)
    fx, fy = to_px(C.SLING_X, C.SLING_Y - 0.45)
    cv2.line(img, (round(bx), round(by)), (round(fx), round(fy)), SLING, 9, cv2.LINE_AA)
    return img


def _sling_arm(img: np.ndarray, dx: float, colour) -> None:
    a = to_px(C.SLING_X, C.SLING_Y - 0.45)
    b = to_px(C.SLING_X + dx, C.SLING_Y + 0.25)
    cv2.line(img, (round(a[0]), round(a[1])), (round(b[0]), round(b[1])), colour, 7, cv2.LINE_AA)


def _cracks(damage: float) -> int:
    return min(4, math.ceil(damage * 4 - 1e-9)) if damage > 0.05 else 0


def _crack_lines(thing_index: int, n: int, poly: list[tuple[float, float]]) -> list[tuple[tuple, tuple]]:
    """`n` crack segments (body coordinates) across a polygon's short side; where they fall
    is fixed per block, so a picture never flickers between frames."""
    xs, ys = [p[0] for p in poly], [p[1] for p in poly]
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    along_x = (x1 - x0) >= (y1 - y0)
    if not along_x:  # work in swapped coordinates, swap back at the end
        x0, x1, y0, y1 = y0, y1, x0, x1
    short = y1 - y0
    out = []
    for k in range(n):
        u = (0.61803 * (k + 1) + 0.37 * thing_index) % 1.0
        cx = x0 + (0.15 + 0.7 * u) * (x1 - x0)
        j = 0.35 * short * (1 if (k + thing_index) % 2 else -1)
        pts = [(cx, y1), (cx + j, y0 + 0.66 * short), (cx - j, y0 + 0.33 * short), (cx, y0)]
        if not along_x:
            pts = [(py, px) for px, py in pts]
        out += list(zip(pts[:-1], pts[1:]))
    return out


def _local_to_world(pose: Pose, p: tuple[float, float]) -> tuple[float, float]:
    c, s = math.cos(pose.angle), math.sin(pose.angle)
    return pose.x + c * p[0] - s * p[1], pose.y + s * p[0] + c * p[1]


def _draw_block(img: np.ndarray, pose: Pose) -> None:
    thing = pose.thing
    fill = _shade(MATERIAL_FILL[thing.material], pose.damage)
    edge = MATERIAL_EDGE[thing.material]
    if thing.radius:
        _circle(img, pose.x, pose.y, thing.radius, fill, edge, 2)
        # A spoke shows the rotation.
        tip = _local_to_world(pose, (thing.radius * 0.8, 0.0))
        a, b = to_px(pose.x, pose.y), to_px(*tip)
        cv2.line(img, (round(a[0]), round(a[1])), (round(b[0]), round(b[1])), edge, 1, cv2.LINE_AA)
        if pose.damage > 0.05:
            for k in range(min(4, math.ceil(pose.damage * 4))):
                ang = pose.angle + 1.3 * k + 0.4
                p0 = to_px(pose.x + 0.2 * thing.radius * math.cos(ang), pose.y + 0.2 * thing.radius * math.sin(ang))
                p1 = to_px(pose.x + 0.9 * thing.radius * math.cos(ang + 0.3),
                           pose.y + 0.9 * thing.radius * math.sin(ang + 0.3))
                cv2.line(img, (round(p0[0]), round(p0[1])), (round(p1[0]), round(p1[1])), CRACK, 1, cv2.LINE_AA)
        return
    polys = [_pts([_local_to_world(pose, p) for p in poly]) for poly in thing.polygons]
    cv2.fillPoly(img, polys, fill, cv2.LINE_AA, _SHIFT)
    cv2.polylines(img, polys, True, edge, 2, cv2.LINE_AA, _SHIFT)
    n = _cracks(pose.damage)
    for i, poly in enumerate(thing.polygons):  # a hollow square cracks wall by wall
        count = n if len(thing.polygons) == 1 else int(i < n)
        for a, b in _crack_lines(thing.index + i, count, poly):
            pa, pb = to_px(*_local_to_world(pose, a)), to_px(*_local_to_world(pose, b))
            cv2.line(img, (round(pa[0]), round(pa[1])), (round(pb[0]), round(pb[1])), CRACK, 2, cv2.LINE_AA)


def _draw_pig(img: np.ndarray, pose: Pose) -> None:
    r = pose.thing.radius
    _circle(img, pose.x, pose.y, r, _shade(PIG_FILL, pose.damage), PIG_EDGE, 2)
    _circle(img, pose.x, pose.y - 0.1 * r, 0.38 * r, PIG_SNOUT, PIG_EDGE, 1)
    for dx in (-0.14, 0.14):
        _circle(img, pose.x + dx * r, pose.y - 0.1 * r, 0.08 * r, PIG_EDGE)
    for dx in (-0.38, 0.38):
        _circle(img, pose.x + dx * r, pose.y + 0.38 * r, 0.2 * r, (255, 255, 255), PIG_EDGE, 1)
        _circle(img, pose.x + dx * r * 1.1, pose.y + 0.36 * r, 0.09 * r, (0, 0, 0))
    if pose.damage > 0.05:  # a bruise
        _circle(img, pose.x - 0.45 * r, pose.y - 0.35 * r, 0.22 * r * (0.5 + pose.damage), (120, 90, 150))


def _draw_tnt(img: np.ndarray, pose: Pose) -> None:
    poly = _pts([_local_to_world(pose, p) for p in pose.thing.polygons[0]])
    cv2.fillPoly(img, [poly], _shade(TNT_FILL, pose.damage), cv2.LINE_AA, _SHIFT)
    cv2.polylines(img, [poly], True, TNT_EDGE, 2, cv2.LINE_AA, _SHIFT)
    cx, cy = to_px(pose.x, pose.y)
    (tw, th), _ = cv2.getTextSize("TNT", cv2.FONT_HERSHEY_SIMPLEX, 0.38, 1)
    cv2.putText(img, "TNT", (round(cx - tw / 2), round(cy + th / 2)), cv2.FONT_HERSHEY_SIMPLEX, 0.38, TNT_TEXT, 1,
                cv2.LINE_AA)


def draw_bird(img: np.ndarray, kind: str, x: float, y: float, angle: float = 0.0) -> None:
    r = C.BIRD_RADIUS[kind]
    fill = BIRD_FILL[kind]
    if kind == "yellow":  # a triangle, as the game draws it
        pts = [(x + r * 1.25 * math.cos(angle + k * 2 * math.pi / 3 + math.pi / 2),
                y + r * 1.25 * math.sin(angle + k * 2 * math.pi / 3 + math.pi / 2)) for k in range(3)]
        poly = _pts(pts)
        cv2.fillPoly(img, [poly], fill, cv2.LINE_AA, _SHIFT)
        cv2.polylines(img, [poly], True, (120, 90, 10), 1, cv2.LINE_AA, _SHIFT)
    else:
        _circle(img, x, y, r, fill, (40, 20, 20) if kind != "black" else (10, 10, 10), 1)
    if kind == "black":  # the fuse
        a, b = to_px(x, y + r), to_px(x + 0.3 * r, y + 1.5 * r)
        cv2.line(img, (round(a[0]), round(a[1])), (round(b[0]), round(b[1])), (90, 70, 50), 2, cv2.LINE_AA)
        _circle(img, x + 0.3 * r, y + 1.5 * r, 0.2 * r, (255, 200, 40))
    # Eyes and beak face right.
    _circle(img, x + 0.35 * r, y + 0.25 * r, 0.22 * r, (255, 255, 255))
    _circle(img, x + 0.42 * r, y + 0.25 * r, 0.1 * r, (0, 0, 0))
    beak = _pts([(x + 0.55 * r, y - 0.05 * r), (x + 1.25 * r, y - 0.2 * r), (x + 0.55 * r, y - 0.4 * r)])
    cv2.fillPoly(img, [beak], BEAK, cv2.LINE_AA, _SHIFT)


def _draw_trails(img: np.ndarray, trails: Sequence[Sequence[tuple[float, float]]]) -> None:
    for trail in trails:
        for k, (x, y) in enumerate(trail[1:], 1):
            _circle(img, x, y, 0.05 if k % 3 else 0.07, TRAIL, TRAIL_EDGE, 1)


def render(level: Level, poses: Sequence[Pose], *, waiting: Sequence[str] = (), trails=(),
           blasts: Sequence[tuple[float, float, float]] = ()) -> np.ndarray:
    """The scene: `waiting` birds in launch order (the first sits in the slingshot)."""
    img = _background().copy()
    for p in level.platforms:
        corners = [(-p.w / 2, -p.h / 2), (p.w / 2, -p.h / 2), (p.w / 2, p.h / 2), (-p.w / 2, p.h / 2)]
        a = math.radians(p.angle)
        poly = _pts([(p.x + math.cos(a) * u - math.sin(a) * v, p.y + math.sin(a) * u + math.cos(a) * v)
                     for u, v in corners])
        cv2.fillPoly(img, [poly], PLATFORM, cv2.LINE_AA, _SHIFT)
        cv2.polylines(img, [poly], True, PLATFORM_EDGE, 2, cv2.LINE_AA, _SHIFT)
    for t in level.terrain:
        poly = _pts(t.points)
        cv2.fillPoly(img, [poly], PLATFORM, cv2.LINE_AA, _SHIFT)
        cv2.polylines(img, [poly], True, PLATFORM_EDGE, 2, cv2.LINE_AA, _SHIFT)
    _draw_trails(img, trails)
    _sling_arm(img, 0.18, SLING_DARK)  # back arm
    queue = waiting[1:]  # next bird nearest the slingshot; a long queue closes up to stay in view
    gap = min(0.5, (C.SLING_X - 0.55 - 0.25) / max(len(queue) - 1, 1))
    for k, kind in reversed(list(enumerate(queue))):  # the nearest drawn last, on top
        draw_bird(img, kind, C.SLING_X - 0.55 - gap * k, C.GROUND_Y + C.BIRD_RADIUS[kind])
    if waiting:
        draw_bird(img, waiting[0], C.SLING_X, C.SLING_Y)
    for pose in poses:
        kind = pose.thing.kind
        if kind == "block":
            _draw_block(img, pose)
        elif kind == "pig":
            _draw_pig(img, pose)
        elif kind == "tnt":
            _draw_tnt(img, pose)
        else:
            draw_bird(img, pose.thing.bird, pose.x, pose.y, 0.0)
    _sling_arm(img, -0.18, SLING)  # front arm
    if blasts:  # a translucent flash over the blast radius, so what it hits stays visible
        flash = img.copy()
        for x, y, radius in blasts:
            cx, cy = to_px(x, y)
            cv2.circle(flash, (round(cx), round(cy)), round(radius * SCALE), BLAST, -1, cv2.LINE_AA)
        img = cv2.addWeighted(flash, 0.45, img, 0.55, 0.0)
        for x, y, radius in blasts:
            cx, cy = to_px(x, y)
            cv2.circle(img, (round(cx), round(cy)), round(radius * SCALE), BLAST, 2, cv2.LINE_AA)
    return img
