"""Our own high-contrast Kinetix renderer (OpenCV, from the numpy state; no JAX).

Kinetix's pixel renderer is itself a jitted JAX program (another compile per size) and
draws motors and thrusters as tiny textures. Ours draws from the same state:
- white background; shapes filled by role, with a black outline: green = the agent's
  shape that must reach the goal, blue = goal, red = deadly, gray = neutral (dark gray
  when fixed in place, light gray when it moves);
- circles carry a radius line so rotation is visible;
- a controllable motor: an orange disc with a black ring and a cross;
- a thruster: a purple triangle pointing the way it pushes its body when on;
- passive joints: a small white dot ringed black (hinge) or a small black dot (weld).
The annotated render adds a label box M<i> at each controllable motor and T<i> at each
thruster, numbered in action-vector order (control i = the i-th motor / thruster binding
used by the level; several joints sharing a binding share a label and move together).

Geometry: 100 px per world unit, 500x500 px, y up in the world, down in the image.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from deepphy.envs.images import draw_label

SIZE = 500
PPU = 100.0  # pixels per world unit (EnvParams.pixels_per_unit)
NUM_STATIC_FIXATED = 4  # floor + 3 off-screen walls; kinetix draws only the floor

WHITE = (255, 255, 255)
BLACK = (0, 0, 0)
ROLE = {  # (moving, fixed) fill colours, RGB
    0: ((185, 185, 185), (90, 90, 90)),
    1: ((40, 200, 40), (20, 130, 20)),
    2: ((30, 100, 235), (20, 60, 160)),
    3: ((235, 40, 40), (160, 20, 20)),
}
MOTOR = (255, 150, 0)
MOTOR_AUTO = (150, 150, 150)
THRUSTER = (150, 40, 210)
LABEL_BG = (255, 255, 0)


@dataclass(frozen=True)
class Controls:
    """The controllable parts of a level, in action-vector order."""

    motor_bindings: tuple[int, ...]  # the kinetix motor binding of control M<i>
    thruster_bindings: tuple[int, ...]  # the kinetix thruster binding of control T<i>
    motor_joints: tuple[tuple[int, ...], ...]  # joint indices moved by M<i>
    thrusters: tuple[tuple[int, ...], ...]  # thruster indices fired by T<i>


def controls(state: Any) -> Controls:
    j = state.joint
    ctrl = np.asarray(j.active) & np.asarray(j.motor_on) & ~np.asarray(j.is_fixed_joint) & ~np.asarray(state.motor_auto)
    mb = np.asarray(state.motor_bindings)
    motor_bindings = tuple(sorted({int(b) for b in mb[ctrl]}))
    t_active = np.asarray(state.thruster.active).astype(bool)
    tb = np.asarray(state.thruster_bindings)
    thruster_bindings = tuple(sorted({int(b) for b in tb[t_active]}))
    return Controls(
        motor_bindings=motor_bindings,
        thruster_bindings=thruster_bindings,
        motor_joints=tuple(tuple(int(i) for i in np.flatnonzero(ctrl & (mb == b))) for b in motor_bindings),
        thrusters=tuple(tuple(int(i) for i in np.flatnonzero(t_active & (tb == b))) for b in thruster_bindings),
    )


def _px(p: np.ndarray) -> np.ndarray:
    """World (x, y) -> image (col, row) as floats."""
    p = np.asarray(p, np.float64)
    return np.stack([p[..., 0] * PPU, SIZE - p[..., 1] * PPU], axis=-1)


def _rot(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


SHIFT = 4  # sub-pixel precision for OpenCV drawing
_S = 1 << SHIFT


def _fix(p: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(p) * _S).astype(np.int32)


def _shape_colour(role: int, inverse_mass: float) -> tuple[int, int, int]:
    moving, fixed = ROLE.get(int(role), ROLE[0])
    return fixed if inverse_mass == 0 else moving


def _thruster_geometry(state: Any, t: int) -> tuple[np.ndarray, np.ndarray]:
    """Image position and unit push direction (image coordinates) of thruster `t`."""
    th = state.thruster
    idx = int(th.object_index[t])
    n_poly = state.polygon.position.shape[0]
    parent_rot = float(state.polygon.rotation[idx]) if idx < n_poly else float(state.circle.rotation[idx - n_poly])
    angle = float(th.rotation[t]) + parent_rot
    d = np.array([np.cos(angle), -np.sin(angle)])  # y flipped
    return _px(th.global_position[t]), d


def render(state: Any, thrusters_on: tuple[int, ...] = ()) -> np.ndarray:
    """The clean scene, RGB uint8 500x500. `thrusters_on`: thruster indices to draw firing."""
    img = np.full((SIZE, SIZE, 3), 255, np.uint8)
    poly, circ = state.polygon, state.circle

    # Polygons (index 0 is the floor; 1..3 are off-screen walls).
    for i in range(poly.position.shape[0]):
        if not bool(poly.active[i]) or 0 < i < NUM_STATIC_FIXATED:
            continue
        n = int(poly.n_vertices[i])
        verts = poly.position[i] + (_rot(float(poly.rotation[i])) @ np.asarray(poly.vertices[i][:n]).T).T
        pts = _fix(_px(verts)).reshape(-1, 1, 2)
        colour = _shape_colour(state.polygon_shape_roles[i], float(poly.inverse_mass[i]))
        cv2.fillPoly(img, [pts], colour, cv2.LINE_AA, SHIFT)
        cv2.polylines(img, [pts], True, BLACK, 2, cv2.LINE_AA, SHIFT)

    # Circles, with a radius line showing their rotation.
    for i in range(circ.position.shape[0]):
        if not bool(circ.active[i]):
            continue
        c = _px(circ.position[i])
        r = float(circ.radius[i]) * PPU
        colour = _shape_colour(state.circle_shape_roles[i], float(circ.inverse_mass[i]))
        cv2.circle(img, tuple(_fix(c)), int(round(r * _S)), colour, -1, cv2.LINE_AA, SHIFT)
        cv2.circle(img, tuple(_fix(c)), int(round(r * _S)), BLACK, 2, cv2.LINE_AA, SHIFT)
        a = float(circ.rotation[i])
        tip = c + r * np.array([np.cos(a), -np.sin(a)])
        cv2.line(img, tuple(_fix(c)), tuple(_fix(tip)), BLACK, 2, cv2.LINE_AA, SHIFT)

    # Joints.
    j = state.joint
    for i in range(j.active.shape[0]):
        if not bool(j.active[i]):
            continue
        c = tuple(_fix(_px(j.global_position[i])))
        if bool(j.is_fixed_joint[i]):
            cv2.circle(img, c, 3 * _S, BLACK, -1, cv2.LINE_AA, SHIFT)
        elif bool(j.motor_on[i]):
            fill = MOTOR_AUTO if bool(state.motor_auto[i]) else MOTOR
            cv2.circle(img, c, 8 * _S, fill, -1, cv2.LINE_AA, SHIFT)
            cv2.circle(img, c, 8 * _S, BLACK, 2, cv2.LINE_AA, SHIFT)
            cx, cy = c
            d = 5 * _S
            cv2.line(img, (cx - d, cy), (cx + d, cy), BLACK, 2, cv2.LINE_AA, SHIFT)
            cv2.line(img, (cx, cy - d), (cx, cy + d), BLACK, 2, cv2.LINE_AA, SHIFT)
        else:
            cv2.circle(img, c, 4 * _S, WHITE, -1, cv2.LINE_AA, SHIFT)
            cv2.circle(img, c, 4 * _S, BLACK, 1, cv2.LINE_AA, SHIFT)

    # Thrusters: a triangle pointing where it pushes; a flame behind it while firing.
    th = state.thruster
    for t in range(th.active.shape[0]):
        if not bool(th.active[t]):
            continue
        p, d = _thruster_geometry(state, t)
        n = np.array([-d[1], d[0]])
        if t in thrusters_on:
            flame = np.array([p - d * 6 + n * 6, p - d * 22, p - d * 6 - n * 6])
            cv2.fillPoly(img, [_fix(flame).reshape(-1, 1, 2)], (255, 210, 0), cv2.LINE_AA, SHIFT)
            cv2.polylines(img, [_fix(flame).reshape(-1, 1, 2)], True, (230, 90, 0), 1, cv2.LINE_AA, SHIFT)
        tri = np.array([p + d * 12, p - d * 6 + n * 9, p - d * 6 - n * 9])
        pts = _fix(tri).reshape(-1, 1, 2)
        cv2.fillPoly(img, [pts], THRUSTER, cv2.LINE_AA, SHIFT)
        cv2.polylines(img, [pts], True, BLACK, 2, cv2.LINE_AA, SHIFT)
    return img


LABEL_SCALE = 0.5
_OFFSETS = [(0, -20), (0, 20), (-26, 0), (26, 0), (-22, -20), (22, -20), (-22, 20), (22, 20),
            (0, -40), (0, 40), (-48, 0), (48, 0), (-40, -36), (40, -36), (-40, 36), (40, 36)]


def _predict_box(text: str, centre: tuple[float, float]) -> tuple[int, int, int, int]:
    """The box `draw_label` will fill for `text` at `centre` (same arithmetic)."""
    thickness = max(1, int(round(LABEL_SCALE * 2)))
    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, LABEL_SCALE, thickness)
    w, h = tw + 6, th + base + 6
    x0 = min(max(int(round(centre[0] - w / 2)), 0), SIZE - w)
    y0 = min(max(int(round(centre[1] - h / 2)), 0), SIZE - h)
    return x0, y0, x0 + w, y0 + h


def _overlaps(a: tuple[int, int, int, int], b: tuple[int, int, int, int], margin: int = 1) -> bool:
    return a[0] < b[2] + margin and b[0] < a[2] + margin and a[1] < b[3] + margin and b[1] < a[3] + margin


def annotate(img: np.ndarray, state: Any, ctl: Controls) -> tuple[np.ndarray, list[tuple[str, tuple[int, int, int, int]]]]:
    """A copy of `img` with a label at each controllable motor and thruster.

    Labels go next to their part, at a nearby spot that neither overlaps another label nor
    covers a motor or thruster, preferring empty background over the scene's shapes. Returns the image and the label boxes
    [(label, (x0, y0, x1, y1))] (x1, y1 exclusive): the image differs from `img` only
    inside them.
    """
    parts: list[tuple[str, np.ndarray, list[tuple[float, float]]]] = []
    for k, joints in enumerate(ctl.motor_joints):
        for i in joints:
            parts.append((f"M{k}", _px(state.joint.global_position[i]), list(_OFFSETS)))
    for k, ts in enumerate(ctl.thrusters):
        for t in ts:
            p, d = _thruster_geometry(state, t)
            behind = [tuple(-d * r) for r in (34, 48)]  # away from where it pushes, first
            parts.append((f"T{k}", p, behind + list(_OFFSETS)))
    markers = [p for _, p, _ in parts]

    out = img.copy()
    boxes: list[tuple[str, tuple[int, int, int, int]]] = []
    for text, p, offsets in parts:
        best, best_cover = None, 2.0
        for dx, dy in offsets:
            centre = (p[0] + dx, p[1] + dy)
            box = _predict_box(text, centre)
            if any(_overlaps(box, b) for _, b in boxes):
                continue
            if any(box[0] - 9 <= m[0] <= box[2] + 9 and box[1] - 9 <= m[1] <= box[3] + 9 for m in markers):
                continue
            cover = float((img[box[1] : box[3], box[0] : box[2]] != 255).any(axis=2).mean())  # scene hidden
            if cover < best_cover - 0.05:  # prefer nearer spots unless a farther one hides clearly less
                best, best_cover = centre, cover
            if cover < 0.02:
                break
        if best is None:
            best = (p[0] + offsets[0][0], p[1] + offsets[0][1])
        boxes.append((text, draw_label(out, text, best, scale=LABEL_SCALE, background=LABEL_BG)))
    return out, boxes


def goal_distance_px(state: Any) -> float | None:
    """Shortest centre-to-centre distance between a green and a blue shape, in pixels."""
    pos = np.concatenate([np.asarray(state.polygon.position), np.asarray(state.circle.position)])
    roles = np.concatenate([np.asarray(state.polygon_shape_roles), np.asarray(state.circle_shape_roles)])
    active = np.concatenate([np.asarray(state.polygon.active), np.asarray(state.circle.active)]).astype(bool)
    green = pos[active & (roles == 1)]
    blue = pos[active & (roles == 2)]
    if len(green) == 0 or len(blue) == 0:
        return None
    d = np.linalg.norm(green[:, None, :] - blue[None, :, :], axis=-1)
    return float(d.min() * PPU)
