"""Top-down OpenCV rendering of a pooltool table (no panda3d)."""

from __future__ import annotations

import math

import cv2
import numpy as np

from deepphy.envs.images import FONT
from deepphy.envs.pooltool.sim import FOOT_SPOT, HEAD_SPOT, _ball_params

# -- rendering ------------------------------------------------------------------------

SCALE = 380.0  # pixels per metre: the table (1.98 m x 0.99 m) renders at 825 x 449 px
MARGIN = 0.11  # metres of rail drawn around the playing surface
RAIL, CUSHION, CLOTH, NOSE, POCKET = (92, 58, 30), (18, 92, 52), (28, 128, 72), (12, 70, 38), (8, 8, 8)
BALL_COLOURS: dict[str, tuple[int, int, int]] = {
    "cue": (250, 250, 245),
    "1": (245, 200, 0), "2": (20, 70, 200), "3": (215, 35, 35), "4": (110, 45, 150),
    "5": (250, 120, 10), "6": (0, 120, 55), "7": (125, 25, 35), "8": (15, 15, 15),
    "9": (245, 200, 0),  # a stripe: drawn as a yellow band on white
}
DARK_BALLS = {"2", "3", "4", "6", "7", "8"}  # numbers written in white on these
TARGET_RING = (255, 40, 200)
AIM_LINE = (235, 235, 235)
TRACE = (255, 255, 255)


def _to_px(x: float, y: float) -> tuple[int, int]:
    """Table (x across, y along) -> image (u right, v down): the long axis is horizontal,
    the head rail (where the break starts) on the left, the rack on the right."""
    return int(round((y + MARGIN) * SCALE)), int(round((x + MARGIN) * SCALE))


def render_table(system, *, target: str | None = None, traces: dict[str, np.ndarray] | None = None) -> np.ndarray:
    table = system.table
    R = _ball_params().R
    width = int(round((table.l + 2 * MARGIN) * SCALE))
    height = int(round((table.w + 2 * MARGIN) * SCALE))
    img = np.empty((height, width, 3), np.uint8)
    img[:] = RAIL
    cw = 0.045
    cv2.rectangle(img, _to_px(-cw, -cw), _to_px(table.w + cw, table.l + cw), CUSHION, -1)
    cv2.rectangle(img, _to_px(0, 0), _to_px(table.w, table.l), CLOTH, -1)
    # head string and the head / foot spots, faintly (ball in hand and respot places)
    head = HEAD_SPOT[1] * table.l
    cv2.line(img, _to_px(0, head), _to_px(table.w, head), (60, 150, 95), 1, cv2.LINE_AA)
    for fx, fy in (HEAD_SPOT, FOOT_SPOT):
        cv2.circle(img, _to_px(fx * table.w, fy * table.l), 3, (60, 150, 95), -1, cv2.LINE_AA)
    for seg in table.cushion_segments.linear.values():
        cv2.line(img, _to_px(seg.p1[0], seg.p1[1]), _to_px(seg.p2[0], seg.p2[1]), NOSE, 2, cv2.LINE_AA)
    for seg in table.cushion_segments.circular.values():
        cv2.circle(img, _to_px(seg.center[0], seg.center[1]), max(1, int(round(seg.radius * SCALE))), NOSE, -1, cv2.LINE_AA)
    for pocket in table.pockets.values():
        cv2.circle(img, _to_px(pocket.center[0], pocket.center[1]), int(round(pocket.radius * SCALE)), POCKET, -1, cv2.LINE_AA)

    balls = {b.id: b for b in system.balls.values() if b.state.s != 4}
    if traces:
        for ball_id, path in traces.items():
            pts = np.array([_to_px(x, y) for x, y in path], np.int32)
            if len(pts) > 1:
                colour = TRACE if ball_id == "cue" else BALL_COLOURS[ball_id]
                cv2.polylines(img, [pts], False, colour, 1, cv2.LINE_AA)
    if target is not None and target in balls and "cue" in balls:
        a = balls["cue"].state.rvw[0][:2]
        b = balls[target].state.rvw[0][:2]
        _dashed(img, _to_px(*a), _to_px(*b), AIM_LINE)
    r = R * SCALE
    for ball_id, ball in balls.items():
        x, y = ball.state.rvw[0][:2]
        c = _to_px(x, y)
        ri = int(round(r))
        if ball_id == "9":
            cv2.circle(img, c, ri, BALL_COLOURS["cue"], -1, cv2.LINE_AA)
            band = np.zeros_like(img[..., 0])
            cv2.circle(band, c, ri, 255, -1, cv2.LINE_AA)
            stripe = np.zeros_like(band)
            h = max(2, int(round(r * 0.55)))
            cv2.rectangle(stripe, (c[0] - ri - 1, c[1] - h), (c[0] + ri + 1, c[1] + h), 255, -1)
            mask = (band > 127) & (stripe > 0)
            img[mask] = BALL_COLOURS["9"]
        else:
            cv2.circle(img, c, ri, BALL_COLOURS[ball_id], -1, cv2.LINE_AA)
        cv2.circle(img, c, ri, (0, 0, 0), 1, cv2.LINE_AA)
        if ball_id != "cue":
            text_colour = (255, 255, 255) if ball_id in DARK_BALLS else (0, 0, 0)
            (tw, th), _ = cv2.getTextSize(ball_id, FONT, 0.45, 1)
            cv2.putText(img, ball_id, (c[0] - tw // 2, c[1] + th // 2), FONT, 0.45, text_colour, 1, cv2.LINE_AA)
        if ball_id == target:
            cv2.circle(img, c, ri + 4, TARGET_RING, 2, cv2.LINE_AA)
    return img


def _dashed(img: np.ndarray, p: tuple[int, int], q: tuple[int, int], colour, dash: int = 8) -> None:
    length = math.hypot(q[0] - p[0], q[1] - p[1])
    n = int(length // dash)
    for i in range(0, n, 2):
        a = (int(p[0] + (q[0] - p[0]) * i / n), int(p[1] + (q[1] - p[1]) * i / n))
        b = (int(p[0] + (q[0] - p[0]) * (i + 1) / n), int(p[1] + (q[1] - p[1]) * (i + 1) / n))
        cv2.line(img, a, b, colour, 1, cv2.LINE_AA)


def _traces(system, moved: set[str]) -> dict[str, np.ndarray]:
    """Ball paths during the last shot, from the event history (straight between events,
    which is exact for rolling balls and close for the short sliding phases)."""
    out = {}
    for ball_id in sorted(moved):  # a fixed drawing order: set order varies with PYTHONHASHSEED
        hist = system.balls[ball_id].history
        out[ball_id] = np.array([s.rvw[0][:2] for s in hist.states])
    return out
