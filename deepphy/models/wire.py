"""Helpers shared by the HTTP clients and the local server: context header, image
budget, token estimates, retry hints, extra body fields."""

from __future__ import annotations

import base64
import email.utils
import json
import math
import re
import struct
import time
import zlib
from typing import Any, Mapping

from deepphy.chat import ImagePart, Message, TextPart
from deepphy.models.base import RequestContext

# The local MOCK server needs the RequestContext; real providers must never see it in the
# messages. Clients whose config sets `send_context` (allowed for loopback URLs only) send
# it in this header as base64url(zlib(JSON)); the request body stays exactly what a real
# provider would get.
CONTEXT_HEADER = "X-Deepphy-Context"

# The first Anthropic API version (versions are ISO dates) whose Messages API has no
# sampling parameters: temperature, top_p or top_k is a 400 there, whatever its value.
ANTHROPIC_NO_SAMPLING_FROM = "2026-10-21"


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
            n += text_tokens(p.text) if isinstance(p, TextPart) else image_tokens(p.image.load())
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


def merge_body(body: dict[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """`body` with `extra` merged in, objects key by key: an extra
    `{"generationConfig": {"thinkingConfig": ...}}` adds to our generationConfig instead of
    replacing it (and with it maxOutputTokens, temperature and seed)."""
    out = dict(body)
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), dict):
            out[key] = merge_body(out[key], value)
        else:
            out[key] = value
    return out


_DURATION = re.compile(r"^\s*(\d+(?:\.\d*)?)s\s*$")


def parse_retry_after(headers: Mapping[str, str], now: float | None = None, body: bytes = b"") -> float | None:
    """Seconds to wait from `retry-after-ms`, or `Retry-After` (seconds or an HTTP date), or
    else from the error body's google.rpc.RetryInfo `retryDelay` (how Gemini says it)."""
    ms = headers.get("retry-after-ms")
    if ms:
        try:
            return max(0.0, float(ms) / 1000)
        except ValueError:
            pass
    value = headers.get("Retry-After")
    if not value:
        return retry_info_delay(body)
    try:
        return max(0.0, float(value))
    except ValueError:
        pass
    try:
        when = email.utils.parsedate_to_datetime(value).timestamp()
    except (TypeError, ValueError):
        return None
    return max(0.0, when - (time.time() if now is None else now))


def retry_info_delay(body: bytes) -> float | None:
    """`retryDelay` (a protobuf Duration such as "22s") of a google.rpc.RetryInfo detail in a
    {"error": {"details": [...]}} body; None if there is none."""
    if b"RetryInfo" not in body:
        return None
    try:
        details = json.loads(body)["error"]["details"]
        delays = [d["retryDelay"] for d in details if str(d.get("@type", "")).endswith("google.rpc.RetryInfo")]
    except (ValueError, KeyError, TypeError, AttributeError):
        return None
    match = _DURATION.match(str(delays[0])) if delays else None
    return float(match.group(1)) if match else None
