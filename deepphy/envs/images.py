"""Drawing helpers shared by the environments' renderers (the `Image` type is in deepphy.chat)."""

from __future__ import annotations

import cv2
import numpy as np

from deepphy.chat import Image  # noqa: F401 - re-exported for renderers

FONT = cv2.FONT_HERSHEY_SIMPLEX


def draw_label(
    img: np.ndarray,
    text: str,
    center: tuple[float, float],
    *,
    scale: float = 0.6,
    color: tuple[int, int, int] = (0, 0, 0),
    background: tuple[int, int, int] = (255, 255, 0),
) -> tuple[int, int, int, int]:
    """Draw `text` in a filled box centred on `center` (clamped inside the image).

    Returns the box (x0, y0, x1, y1) so callers and tests know exactly where it went.
    """
    thickness = max(1, int(round(scale * 2)))
    (tw, th), base = cv2.getTextSize(text, FONT, scale, thickness)
    pad = 3
    w, h = tw + 2 * pad, th + base + 2 * pad
    x0 = int(round(center[0] - w / 2))
    y0 = int(round(center[1] - h / 2))
    x0 = min(max(x0, 0), img.shape[1] - w)
    y0 = min(max(y0, 0), img.shape[0] - h)
    cv2.rectangle(img, (x0, y0), (x0 + w - 1, y0 + h - 1), background, -1)
    cv2.rectangle(img, (x0, y0), (x0 + w - 1, y0 + h - 1), color, 1)
    cv2.putText(img, text, (x0 + pad, y0 + pad + th), FONT, scale, color, thickness, cv2.LINE_AA)
    return x0, y0, x0 + w, y0 + h


def stack_frames(frames: list[np.ndarray], captions: list[str] | None = None, height: int = 300) -> np.ndarray:
    """Place frames side by side, scaled to `height`, with an optional caption on each."""
    out = []
    for i, f in enumerate(frames):
        f = cv2.resize(f, (round(f.shape[1] * height / f.shape[0]), height), interpolation=cv2.INTER_AREA)
        if captions:
            draw_label(f, captions[i], (f.shape[1] / 2, 12), scale=0.45, background=(255, 255, 255))
        out.append(f)
        if i < len(frames) - 1:
            out.append(np.full((f.shape[0], 4, 3), 128, np.uint8))
    return np.concatenate(out, axis=1)
