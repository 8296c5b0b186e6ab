"""Drawing PHYRE scenes: the task's bodies (and the placed ball) at any poses, with OpenCV.

Colours are PHYRE's own palette (`phyre.vis.WAD_COLORS`): black static, gray dynamic,
green the goal's subject, blue a dynamic goal object, purple a static goal object, red
the placed ball. The scene is 256 x 256 px with y up; images are drawn y down at any size.
"""

from __future__ import annotations

import math
from typing import Sequence

import cv2
import numpy as np

from deepphy.envs.phyre.data import PhyreTask
from deepphy.envs.phyre.space import SCENE, Ball

COLORS: dict[str, tuple[int, int, int]] = {  # RGB
    "red": (0xF3, 0x4F, 0x46),
    "green": (0x6B, 0xCE, 0xBB),
    "blue": (0x18, 0x77, 0xF2),
    "purple": (0x4B, 0x4A, 0xA4),
    "gray": (0xB9, 0xCA, 0xD2),
    "black": (0, 0, 0),
}
_SHIFT = 4  # sub-pixel bits for cv2


def render(task: PhyreTask, ball: Ball | None = None,
           poses: Sequence[tuple[float, float, float]] | None = None, size: int = 512) -> np.ndarray:
    """RGB image (size x size) of the task with the optional ball.

    `poses` gives (x, y, angle) of every dynamic body in order (the ball last), as recorded
    by `sim.simulate`; None draws the initial scene.
    """
    scale = size / SCENE
    mul = scale * (1 << _SHIFT)
    img = np.full((size, size, 3), 255, np.uint8)

    def pt(x: float, y: float) -> tuple[int, int]:
        return int(round(x * mul)), int(round((SCENE - y) * mul))

    # (pose, colour, shapes, dynamic) per body; static first so moving things stay on top
    items = []
    dynamic_index = 0
    for b in task.bodies:
        pose = (b.x, b.y, b.angle)
        if b.dynamic:
            if poses is not None:
                pose = poses[dynamic_index]
            dynamic_index += 1
        items.append((pose, b.color, [(s.polygon, s.radius) for s in b.shapes], b.dynamic))
    if ball is not None:
        pose = poses[dynamic_index] if poses is not None else (float(ball.x), float(ball.y), 0.0)
        items.append((pose, "red", [(None, float(ball.r))], True))
    items.sort(key=lambda item: item[3])

    for (x, y, angle), color, shapes, dynamic in items:
        rgb = COLORS[color]
        c, s = math.cos(angle), math.sin(angle)
        for polygon, radius in shapes:
            if polygon is None:
                cv2.circle(img, pt(x, y), int(round(radius * mul)), rgb, -1, cv2.LINE_AA, _SHIFT)
                if dynamic and radius * scale > 6:  # a darker spoke shows rotation
                    end = pt(x + c * radius * 0.8, y + s * radius * 0.8)
                    shade = tuple(int(v * 0.6) for v in rgb)
                    cv2.line(img, pt(x, y), end, shade, max(1, int(scale)), cv2.LINE_AA, _SHIFT)
            else:
                corners = np.array([pt(x + c * vx - s * vy, y + s * vx + c * vy) for vx, vy in polygon], np.int32)
                cv2.fillPoly(img, [corners], rgb, cv2.LINE_AA, _SHIFT)
    return img
