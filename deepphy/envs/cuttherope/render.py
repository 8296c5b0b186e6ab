"""The screenshot the model sees (OpenCV, RGB, 480 x 720, one pixel per world unit).

Legend (the prompt repeats it):
- candy: red disc with white stripes (box 5: two smaller pink halves);
- Om Nom: the round green creature with an open mouth (dark red) in his middle; the whole
  green disc is where he catches the candy;
- walls: thick brown bars with a light edge;
- ropes: brown lines from a pin to the candy, redder the more they are stretched (fully red
  at ROPE_RED_STRETCH px); a slack rope sags;
- pins: dark gray dots labelled P1, P2, ...; a hook on a track slides along a light gray
  groove with a stop at each end;
- active pins: blue dots inside a dashed blue circle, labelled A1, ...: a rope attaches
  when the candy enters the circle (faded once used);
- bubbles: light blue rings labelled B1, ... (the label follows the bubble);
- air cushions: blue-gray boxes with an arrow in the direction they puff, labelled C1, ...;
  the faint band in front of one is the reach of its puff;
- magic hats: black hats with a coloured band, pairs share the colour (white labels H1 ...);
- spikes: dark gray teeth; electric barriers: yellow zigzag when live, gray dashed when off
  (white labels E1, ...);
- spiders: black, on a rope; stars: gold.
Labels of elements the actions name are yellow boxes; the others are white.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from deepphy.envs.cuttherope import constants as C
from deepphy.envs.cuttherope.sim import World, direction
from deepphy.envs.images import FONT, draw_label

BACKGROUND = (240, 228, 204)
BORDER = (170, 140, 100)
ROPE = (125, 80, 35)
ROPE_TAUT = (225, 25, 25)
PIN = (70, 70, 75)
ACTIVE = (30, 90, 220)
FADED = (185, 175, 160)
BUBBLE = (110, 175, 240)
CUSHION = (95, 115, 140)
CANDY = (225, 35, 55)
HALF = (240, 110, 170)
STAR = (255, 200, 20)
STAR_EDGE = (185, 120, 0)
OMNOM = (90, 185, 60)
MOUTH = (120, 20, 30)
SPIKE = (75, 75, 85)
WALL = (120, 85, 50)
TRACK = (150, 150, 160)
WALL_EDGE = (200, 170, 120)
ELECTRIC = (250, 230, 40)
SPIDER = (25, 25, 25)
TRAIL = (200, 40, 200)
HAT_COLOURS = ((150, 60, 200), (20, 160, 160), (235, 130, 20), (220, 60, 140))
YELLOW, WHITE, BLACK = (255, 255, 0), (255, 255, 255), (0, 0, 0)
LABEL_SCALE = 0.5


def render(world: World, *, labels: bool = True, trail: bool = False, banner: str | None = None,
           clock: bool = False) -> np.ndarray:
    """The world as an RGB image. `trail` draws the candy's path during the last advance;
    `banner` writes a line across the top (the outcome, in key frames); the corner shows the
    stars collected, and with `clock` the world's time (the state_text option)."""
    img = np.full((C.HEIGHT, C.WIDTH, 3), BACKGROUND, np.uint8)
    cv2.rectangle(img, (0, 0), (C.WIDTH - 1, C.HEIGHT - 1), BORDER, 2)
    level = world.level
    taken: list[tuple[int, int, int, int]] = []
    todo: list[tuple[str, tuple[float, float], float, bool]] = []  # (text, anchor, radius, actionable)

    for k, cushion in enumerate(level.cushions):
        _cushion_reach(img, cushion.pos, cushion.angle)
    for k, e in enumerate(level.electrics):
        _electric(img, e.a, e.b, world.electric_live(k))
        todo.append((f"E{k + 1}", ((e.a[0] + e.b[0]) / 2, (e.a[1] + e.b[1]) / 2), 14, False))
    for pin in level.pins:
        if pin.track:
            _track(img, pin.pos, pin.track.to)
    for s in level.spikes:
        _spikes(img, s.a, s.b)
    for w in level.walls:
        _wall(img, w.a, w.b)
    for k, a in enumerate(world.active_pins):
        live = a.state in ("armed", "attached")
        if a.state == "armed":
            _dashed_circle(img, (a.x, a.y), a.radius, ACTIVE, 2)
        cv2.circle(img, _pt((a.x, a.y)), int(C.PIN_RADIUS), ACTIVE if live else FADED, -1, cv2.LINE_AA)
        cv2.circle(img, _pt((a.x, a.y)), int(C.PIN_RADIUS), WHITE, 1, cv2.LINE_AA)
        if live:
            todo.append((f"A{k + 1}", (a.x, a.y), C.PIN_RADIUS + 4, True))
    for k, pair in enumerate(level.hats):
        for h, hat in enumerate(pair.hats):
            _hat(img, hat.pos, hat.angle, HAT_COLOURS[k % len(HAT_COLOURS)])
            todo.append((f"H{k + 1}", hat.pos, C.HAT_RADIUS, False))
    for k, cushion in enumerate(level.cushions):
        _cushion(img, cushion.pos, cushion.angle)
        todo.append((f"C{k + 1}", cushion.pos, C.CUSHION_SIZE * 0.8, True))
    _om_nom(img, level.om_nom)
    for k, star in enumerate(level.stars):
        if not world.stars[k]:
            _star(img, star)

    rope_paths = {}
    for rope in world.ropes:
        c = world.candies[rope.candy]
        path = _rope_path((rope.ax, rope.ay), (c.x, c.y), rope.length)
        rope_paths[(rope.source, rope.sid)] = path
        f = min(1.0, max(0.0, world.rope_stretch(rope) / C.ROPE_RED_STRETCH))
        colour = tuple(int(round(a + (b - a) * f)) for a, b in zip(ROPE, ROPE_TAUT))
        cv2.polylines(img, [np.round(path).astype(np.int32)], False, colour, 3, cv2.LINE_AA)
    for k, pin in enumerate(level.pins):
        attached = world.rope_of_pin(k + 1) is not None
        at = pin.at(world.time)
        cv2.circle(img, _pt(at), int(C.PIN_RADIUS), PIN if attached else FADED, -1, cv2.LINE_AA)
        cv2.circle(img, _pt(at), int(C.PIN_RADIUS) - 3, (200, 200, 200), -1, cv2.LINE_AA)
        if attached:
            todo.append((f"P{k + 1}", at, C.PIN_RADIUS + 4, True))
    for s in world.spiders:
        path = rope_paths.get(("pin", s.pin))
        if s.gone or path is None:
            continue
        _spider(img, _along(path, world.spider_position(s)))

    if trail and len(world.trail) > 1:
        for p in world.trail:
            cv2.circle(img, _pt(p), 2, TRAIL, -1, cv2.LINE_AA)
    for c in world.candies:
        if c.alive:
            _candy(img, (c.x, c.y), c.radius, HALF if c.half else CANDY)
    for k, b in enumerate(world.bubbles):
        if not b.popped:
            _bubble(img, (b.x, b.y))
            todo.append((f"B{k + 1}", (b.x, b.y), C.BUBBLE_RADIUS * 0.75, True))

    if labels:
        for text, anchor, radius, actionable in todo:
            _place_label(img, text, anchor, radius, YELLOW if actionable else WHITE, taken)
    status = (f"t = {world.time:.2f} s   " if clock else "") + f"stars {world.stars_collected}/{len(level.stars)}"
    cv2.putText(img, status, (8, C.HEIGHT - 10), FONT, 0.45, (90, 70, 40), 1, cv2.LINE_AA)
    if banner:
        draw_label(img, banner, (C.WIDTH / 2, 16), scale=0.5, background=WHITE)
    return img


# -- elements -------------------------------------------------------------------------------------


def _pt(p) -> tuple[int, int]:
    return int(round(p[0])), int(round(p[1]))


def _blend(img: np.ndarray, overlay: np.ndarray, alpha: float) -> None:
    cv2.addWeighted(overlay, alpha, img, 1 - alpha, 0, dst=img)


def _rope_path(a, b, length: float) -> np.ndarray:
    """The drawn rope: straight when taut, a sagging parabola when slack (its arc length
    close to the rope's rest length)."""
    d = math.dist(a, b)
    if length - d <= 0.0:
        return np.array([a, b], float)
    sag = min(length / 2, math.sqrt(3.0 / 8.0 * max(d, 1.0) * (length - d)))
    mid = ((a[0] + b[0]) / 2, (a[1] + b[1]) / 2 + 2 * sag)  # control point of a quadratic Bezier
    t = np.linspace(0, 1, 24)[:, None]
    return (1 - t) ** 2 * np.array(a) + 2 * (1 - t) * t * np.array(mid) + t ** 2 * np.array(b)


def _along(path: np.ndarray, fraction: float) -> tuple[float, float]:
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    total = float(seg.sum())
    if total == 0:
        return tuple(path[0])
    target = fraction * total
    for i, s in enumerate(seg):
        if target <= s or i == len(seg) - 1:
            u = 0.0 if s == 0 else min(1.0, target / s)
            p = path[i] + u * (path[i + 1] - path[i])
            return float(p[0]), float(p[1])
        target -= s
    return tuple(path[-1])


def _dashed_circle(img, centre, radius, colour, thickness) -> None:
    n = max(12, int(radius / 5))
    for k in range(0, n, 2):
        a0, a1 = 360 * k / n, 360 * (k + 1) / n
        cv2.ellipse(img, _pt(centre), (int(radius), int(radius)), 0, a0, a1, colour, thickness, cv2.LINE_AA)


def _candy(img, p, r, colour) -> None:
    cv2.circle(img, _pt(p), int(r), colour, -1, cv2.LINE_AA)
    for k in (-1, 0, 1):  # white stripes
        off = k * r * 0.45
        a = (p[0] - r * 0.6 + off * 0.4, p[1] + r * 0.5 + off)
        b = (p[0] + r * 0.5 + off * 0.4, p[1] - r * 0.6 + off)
        cv2.line(img, _pt(a), _pt(b), WHITE, max(2, int(r / 6)), cv2.LINE_AA)
    cv2.circle(img, _pt(p), int(r), (120, 10, 25), 2, cv2.LINE_AA)


def _bubble(img, p) -> None:
    overlay = img.copy()
    cv2.circle(overlay, _pt(p), int(C.BUBBLE_RADIUS), (205, 230, 255), -1, cv2.LINE_AA)
    _blend(img, overlay, 0.35)
    cv2.circle(img, _pt(p), int(C.BUBBLE_RADIUS), BUBBLE, 2, cv2.LINE_AA)
    cv2.ellipse(img, _pt((p[0] - 12, p[1] - 14)), (9, 5), -40, 0, 360, WHITE, -1, cv2.LINE_AA)


def _star(img, p) -> None:
    pts = []
    for k in range(10):
        r = C.STAR_RADIUS if k % 2 == 0 else C.STAR_RADIUS * 0.45
        a = -math.pi / 2 + k * math.pi / 5
        pts.append((p[0] + r * math.cos(a), p[1] + r * math.sin(a)))
    poly = np.round(np.array(pts)).astype(np.int32)
    cv2.fillPoly(img, [poly], STAR, cv2.LINE_AA)
    cv2.polylines(img, [poly], True, STAR_EDGE, 1, cv2.LINE_AA)


def _om_nom(img, centre) -> None:
    """A round green creature (his disc is his catch zone), eyes above a wide open mouth."""
    mx, my = centre
    r = C.OMNOM_RADIUS
    cv2.circle(img, _pt(centre), int(r), OMNOM, -1, cv2.LINE_AA)
    cv2.circle(img, _pt(centre), int(r), (40, 110, 30), 2, cv2.LINE_AA)
    for side in (-1, 1):
        eye = (mx + side * 0.38 * r, my - 0.58 * r)
        cv2.circle(img, _pt(eye), int(0.2 * r), WHITE, -1, cv2.LINE_AA)
        cv2.circle(img, _pt(eye), int(0.2 * r), (40, 110, 30), 1, cv2.LINE_AA)
        cv2.circle(img, _pt((eye[0], eye[1] + 2)), int(0.1 * r), BLACK, -1, cv2.LINE_AA)
    cv2.ellipse(img, _pt((mx, my + 0.15 * r)), (int(0.62 * r), int(0.45 * r)), 0, 0, 360, MOUTH, -1, cv2.LINE_AA)
    cv2.ellipse(img, _pt((mx, my + 0.38 * r)), (int(0.33 * r), int(0.15 * r)), 0, 0, 360, (220, 80, 90), -1,
                cv2.LINE_AA)
    for side in (-1, 1):  # teeth
        cv2.rectangle(img, _pt((mx + side * 0.2 * r - 3, my - 0.28 * r)), _pt((mx + side * 0.2 * r + 3, my - 0.12 * r)),
                      WHITE, -1)


def _track(img, a, b) -> None:
    """The groove a hook slides along, with a stop at each end."""
    cv2.line(img, _pt(a), _pt(b), TRACK, 6, cv2.LINE_AA)
    cv2.line(img, _pt(a), _pt(b), (235, 225, 210), 2, cv2.LINE_AA)
    for end in (a, b):
        cv2.circle(img, _pt(end), 5, TRACK, -1, cv2.LINE_AA)


def _wall(img, a, b) -> None:
    thickness = int(2 * C.WALL_RADIUS)
    cv2.line(img, _pt(a), _pt(b), WALL, thickness, cv2.LINE_AA)
    cv2.line(img, _pt(a), _pt(b), WALL_EDGE, 2, cv2.LINE_AA)


def _spikes(img, a, b) -> None:
    length = math.dist(a, b)
    n = max(1, int(length / 14))
    ux, uy = (b[0] - a[0]) / max(length, 1e-9), (b[1] - a[1]) / max(length, 1e-9)
    nx, ny = -uy, ux
    cv2.line(img, _pt(a), _pt(b), SPIKE, 5, cv2.LINE_AA)
    for k in range(n):
        s0, s1 = k * length / n, (k + 1) * length / n
        base0 = (a[0] + ux * s0, a[1] + uy * s0)
        base1 = (a[0] + ux * s1, a[1] + uy * s1)
        mid = (a[0] + ux * (s0 + s1) / 2, a[1] + uy * (s0 + s1) / 2)
        for side in (-1, 1):
            tip = (mid[0] + side * nx * C.SPIKE_TOOTH, mid[1] + side * ny * C.SPIKE_TOOTH)
            tri = np.round(np.array([base0, tip, base1])).astype(np.int32)
            cv2.fillPoly(img, [tri], SPIKE, cv2.LINE_AA)
            cv2.polylines(img, [tri], True, (160, 160, 170), 1, cv2.LINE_AA)


def _electric(img, a, b, live: bool) -> None:
    for end in (a, b):
        cv2.circle(img, _pt(end), 6, (90, 90, 100), -1, cv2.LINE_AA)
    if not live:
        length = math.dist(a, b)
        n = max(2, int(length / 10))
        for k in range(0, n, 2):
            p = (a[0] + (b[0] - a[0]) * k / n, a[1] + (b[1] - a[1]) * k / n)
            q = (a[0] + (b[0] - a[0]) * (k + 1) / n, a[1] + (b[1] - a[1]) * (k + 1) / n)
            cv2.line(img, _pt(p), _pt(q), (150, 150, 150), 2, cv2.LINE_AA)
        return
    length = math.dist(a, b)
    ux, uy = (b[0] - a[0]) / max(length, 1e-9), (b[1] - a[1]) / max(length, 1e-9)
    n = max(2, int(length / 8))
    pts = []
    for k in range(n + 1):
        s = k * length / n
        off = 0 if k in (0, n) else (7 if k % 2 else -7)
        pts.append((a[0] + ux * s - uy * off, a[1] + uy * s + ux * off))
    poly = np.round(np.array(pts)).astype(np.int32)
    cv2.polylines(img, [poly], False, (255, 250, 200), 6, cv2.LINE_AA)
    cv2.polylines(img, [poly], False, ELECTRIC, 3, cv2.LINE_AA)
    cv2.polylines(img, [poly], False, (60, 110, 230), 1, cv2.LINE_AA)


def _spider(img, p) -> None:
    for side in (-1, 1):
        for k in range(4):
            ang = math.radians(-50 + k * 33)
            end = (p[0] + side * 14 * math.cos(ang), p[1] + 14 * math.sin(ang))
            knee = (p[0] + side * 9 * math.cos(ang), p[1] + 9 * math.sin(ang) - 4)
            cv2.line(img, _pt(p), _pt(knee), SPIDER, 2, cv2.LINE_AA)
            cv2.line(img, _pt(knee), _pt(end), SPIDER, 2, cv2.LINE_AA)
    cv2.circle(img, _pt(p), 7, SPIDER, -1, cv2.LINE_AA)
    for side in (-1, 1):
        cv2.circle(img, _pt((p[0] + side * 3, p[1] - 2)), 2, (230, 30, 30), -1, cv2.LINE_AA)


def _rotated(centre, angle_deg: float, pts) -> np.ndarray:
    """Points given in a frame whose +x is the direction `angle_deg`, moved to `centre`."""
    ux, uy = direction(angle_deg)
    vx, vy = -uy, ux
    return np.round(np.array([(centre[0] + x * ux + y * vx, centre[1] + x * uy + y * vy) for x, y in pts])).astype(np.int32)


def _cushion_reach(img, pos, angle) -> None:
    w = C.PUFF_WIDTH / 2
    poly = _rotated(pos, angle, [(0, -w), (C.PUFF_RANGE, -w), (C.PUFF_RANGE, w), (0, w)])
    overlay = img.copy()
    cv2.fillPoly(overlay, [poly], (200, 215, 235), cv2.LINE_AA)
    _blend(img, overlay, 0.35)


def _cushion(img, pos, angle) -> None:
    s = C.CUSHION_SIZE / 2
    body = _rotated(pos, angle, [(-s, -s), (s * 0.4, -s), (s * 0.4, s), (-s, s)])
    nozzle = _rotated(pos, angle, [(s * 0.4, -s * 0.5), (s, -s * 0.3), (s, s * 0.3), (s * 0.4, s * 0.5)])
    cv2.fillPoly(img, [body], CUSHION, cv2.LINE_AA)
    cv2.fillPoly(img, [nozzle], (60, 75, 95), cv2.LINE_AA)
    cv2.polylines(img, [body], True, BLACK, 1, cv2.LINE_AA)
    arrow = _rotated(pos, angle, [(s + 4, 0), (s + 40, 0)])
    cv2.arrowedLine(img, tuple(arrow[0]), tuple(arrow[1]), (60, 75, 95), 2, cv2.LINE_AA, tipLength=0.35)


def _hat(img, pos, angle, band) -> None:
    # The opening at `pos` faces `angle`; the crown lies behind it.
    crown = _rotated(pos, angle, [(-4, -17), (-40, -14), (-40, 14), (-4, 17)])
    brim = _rotated(pos, angle, [(-4, -26), (2, -26), (2, 26), (-4, 26)])
    stripe = _rotated(pos, angle, [(-12, -16), (-20, -15), (-20, 15), (-12, 16)])
    cv2.fillPoly(img, [crown], (30, 30, 35), cv2.LINE_AA)
    cv2.fillPoly(img, [stripe], band, cv2.LINE_AA)
    cv2.fillPoly(img, [brim], (30, 30, 35), cv2.LINE_AA)
    opening = _rotated(pos, angle, [(3, 0)])[0]
    ux, uy = direction(angle)
    cv2.ellipse(img, tuple(int(v) for v in opening), (4, 22), math.degrees(math.atan2(uy, ux)), 0, 360, band, 2,
                cv2.LINE_AA)


def _place_label(img, text, anchor, radius, background, taken) -> None:
    """A label next to its element, at the first of eight positions around it that is
    inside the image and overlaps no earlier label."""
    thickness = max(1, int(round(LABEL_SCALE * 2)))
    (tw, th), base = cv2.getTextSize(text, FONT, LABEL_SCALE, thickness)
    w, h = tw + 6, th + base + 6
    best = None
    for k in range(16):
        ang = math.radians(45 - 45 * (k % 8))
        dist = radius + 4 + (0 if k < 8 else 16) + max(w, h) / 2
        cx, cy = anchor[0] + dist * math.cos(ang), anchor[1] - dist * math.sin(ang)
        box = (int(cx - w / 2), int(cy - h / 2), int(cx + w / 2), int(cy + h / 2))
        inside = box[0] >= 2 and box[1] >= 2 and box[2] <= C.WIDTH - 2 and box[3] <= C.HEIGHT - 2
        if inside and not any(_overlap(box, t) for t in taken):
            best = (cx, cy)
            break
        if best is None and inside:
            best = (cx, cy)
    if best is None:
        best = anchor
    taken.append(draw_label(img, text, best, scale=LABEL_SCALE, background=background))


def _overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]
