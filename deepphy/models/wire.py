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


# A server's context length is a hard limit (vLLM answers 400 past it), and our count is an
# estimate (characters / 4, an image's pixels / 750), not the server's tokenizer: requests are
# fitted into this share of the context.
CONTEXT_SHARE = 0.9


def input_budget(max_context_tokens: int | None, max_tokens: int) -> int | None:
    """The input tokens a request may estimate at on a server with this context length
    (None: no limit), its reply's max_tokens kept free."""
    if max_context_tokens is None:
        return None
    return int(max_context_tokens * CONTEXT_SHARE) - max_tokens


def limit_images(messages: list[Message], max_images: int,
                 max_input_tokens: int | None = None) -> tuple[list[Message], int]:
    """Keep the `max_images` most recent images, and fewer while the request's estimated input
    tokens (`estimate_input_tokens`) exceed `max_input_tokens`; each older image becomes a
    one-line text placeholder (so the text around it still reads). Returns (messages, number
    dropped)."""
    images = [p for m in messages for p in m.content if isinstance(p, ImagePart)]
    by_count = max(0, len(images) - max_images)
    drop = by_count
    if max_input_tokens is not None:
        cost = [image_tokens(p.image.load()) - text_tokens(_omitted(p, i >= by_count))  # saved by dropping it
                for i, p in enumerate(images)]
        total = estimate_input_tokens(messages) - sum(cost[:drop])
        while total > max_input_tokens and drop < len(images):
            total -= cost[drop]
            drop += 1
    if drop == 0:
        return messages, 0
    out, dropped = [], 0
    for m in messages:
        parts = []
        for p in m.content:
            if isinstance(p, ImagePart) and dropped < drop:
                parts.append(TextPart(text=_omitted(p, dropped >= by_count)))
                dropped += 1
            else:
                parts.append(p)
        out.append(Message(role=m.role, content=parts))
    return out, drop


def _omitted(part: ImagePart, for_context: bool) -> str:
    limit = "context length limit" if for_context else "per-request image limit"
    return f"[image omitted ({limit}): {part.image.caption}]"


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
