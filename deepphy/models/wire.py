"""Helpers shared by the HTTP clients and the local server: context header, image
budget, token estimates, Retry-After."""

from __future__ import annotations

import base64
import email.utils
import math
import struct
import time
import zlib
from typing import Mapping

from deepphy.chat import ImagePart, Message, TextPart
from deepphy.models.base import RequestContext

# The local MOCK server needs the RequestContext; real providers must never see it in the
# messages. Clients whose config sets `send_context` (allowed for loopback URLs only) send
# it in this header as base64url(zlib(JSON)); the request body stays exactly what a real
# provider would get.
CONTEXT_HEADER = "X-Deepphy-Context"


def encode_context(ctx: RequestContext) -> str:
    return base64.urlsafe_b64encode(zlib.compress(ctx.model_dump_json().encode(), 6)).decode("ascii")


def decode_context(value: str) -> RequestContext:
    return RequestContext.model_validate_json(zlib.decompress(base64.urlsafe_b64decode(value.encode("ascii"))))


def png_size(png: bytes) -> tuple[int, int]:
    """(width, height) from a PNG header; (0, 0) if it is not one."""
    if len(png) >= 24 and png[:8] == b"\x89PNG\r\n\x1a\n":
        return struct.unpack(">II", png[16:24])
    return 0, 0


def image_tokens(png: bytes) -> int:
    """A provider-neutral estimate of an image's input tokens (Anthropic's w*h/750, capped)."""
    w, h = png_size(png)
    return max(85, min(1600, math.ceil(w * h / 750))) if w and h else 258


def text_tokens(text: str) -> int:
    return math.ceil(len(text) / 4)


def estimate_input_tokens(messages: list[Message]) -> int:
    n = 0
    for m in messages:
        n += 4
        for p in m.content:
            n += text_tokens(p.text) if isinstance(p, TextPart) else image_tokens(p.image.png)
    return n


def limit_images(messages: list[Message], max_images: int) -> tuple[list[Message], int]:
    """Keep the `max_images` most recent images; each older one becomes a one-line text
    placeholder (so the text around it still reads). Returns (messages, number dropped)."""
    total = sum(len(m.images) for m in messages)
    drop = max(0, total - max_images)
    if drop == 0:
        return messages, 0
    out, left = [], drop
    for m in messages:
        parts = []
        for p in m.content:
            if isinstance(p, ImagePart) and left > 0:
                left -= 1
                parts.append(TextPart(text=f"[image omitted (per-request image limit): {p.image.caption}]"))
            else:
                parts.append(p)
        out.append(Message(role=m.role, content=parts))
    return out, drop


def png_b64(png: bytes) -> str:
    return base64.b64encode(png).decode("ascii")


def parse_retry_after(headers: Mapping[str, str], now: float | None = None) -> float | None:
    """Seconds to wait from `retry-after-ms`, or `Retry-After` (seconds or an HTTP date)."""
    ms = headers.get("retry-after-ms")
    if ms:
        try:
            return max(0.0, float(ms) / 1000)
        except ValueError:
            pass
    value = headers.get("Retry-After")
    if not value:
        return None
    try:
        return max(0.0, float(value))
    except ValueError:
        pass
    try:
        when = email.utils.parsedate_to_datetime(value).timestamp()
    except (TypeError, ValueError):
        return None
    return max(0.0, when - (time.time() if now is None else now))
