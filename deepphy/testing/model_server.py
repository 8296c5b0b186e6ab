"""A local model server with real provider wire formats that answers with the MOCK policy.

    python -m deepphy.testing.model_server [--port PORT] [--latency 0.5] [--fault-rate 0.2] [--seed 0]

Routes (real request/response JSON, status codes and headers):
- POST /v1/chat/completions                    OpenAI Chat Completions (no streaming)
- POST /v1/messages                            Anthropic Messages
- POST /v1beta/models/{model}:generateContent  Gemini
- GET  /stats                                  arrival times and counters (?arrivals=0 to omit times)
- GET  /admin/bodies                           the last --record-bodies requests: path, headers
                                               (credentials masked: "Bearer ***"), body (for tests)
- POST /admin/config                           change latency / faults at run time (JSON, partial)
- POST /admin/reset                            clear arrivals, counters and fault history
- GET  /health

With --limit-mm-per-prompt / --max-model-len it also refuses, as a vLLM server does, Chat
Completions requests with more images or more prompt + max_tokens than those limits.

The answer: the server needs the request's RequestContext, which is NOT in the messages
(a real provider must see exactly the prompt). Clients whose model config sets
`send_context: true` (allowed only for loopback base URLs) send it in the
`X-Deepphy-Context` header (base64url of zlib'd JSON, see deepphy.models.wire); the
server answers `deepphy.agents.mock_text(ctx)`, which is byte for byte
what `deepphy.agents.MockModel` returns for the same request. Without the header it
answers 400.

Errors come in each provider's documented shape, with its status codes, request-id
headers and retry hint (see the format classes; tests/test_sdk_conformance.py parses them
with the official SDKs).

Faults (at `--fault-rate`, kinds from `--faults`): `429` (with Retry-After; Gemini: a
RetryInfo detail in the body), `500`,
`hang` (no answer for --hang seconds, past any sane client timeout), `malformed` (200
with truncated JSON), `empty` (200 with no choices / content / candidates), `prose` (200
with a reply that contains no action); and, only when named, `drip` (a 200 whose body
arrives one byte every --drip seconds).
Whether a request is faulted, and how, depends
only on the seed, the request (body + context header) and how many times that same
request arrived before, so a run's faults do not depend on timing or arrival order; a
retry of a request draws again.

Every request's arrival time (time.time() at the server) is kept for GET /stats and,
with --log, appended as a JSON line to a file.
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import ctypes
import hashlib
import json
import os
import re
import secrets
import signal
import subprocess
import sys
import threading
import time
from collections import Counter, deque
from typing import Any

from aiohttp import web
from pydantic import BaseModel, ConfigDict, Field, field_validator

from deepphy.loopback import LOOPBACK_HOST
from deepphy.models.wire import ANTHROPIC_NO_SAMPLING_FROM, CONTEXT_HEADER, decode_context, image_tokens, text_tokens
from deepphy.seeding import seeded_rng

# Where `python -m deepphy.testing.model_server` listens: the shipped models file's `local-mock`
# entry (deepphy/models/models.yaml) points here; a test holds the two equal.
DEFAULT_PORT = 8765
FAULT_KINDS = ("429", "500", "hang", "malformed", "empty", "prose")  # the default kinds
SLOW_FAULTS = ("drip",)  # only when named: a drip ties a request up for as long as the client lets it
PROSE_REPLY = (
    "Looking at the scene, the balls rest on the gray supports and gravity will pull them down "
    "once the supports are gone. I would want to think carefully about the timing of each "
    "removal before committing to anything."
)


class Faults(BaseModel):
    model_config = ConfigDict(extra="forbid")

    rate: float = Field(0.0, ge=0, le=1)
    kinds: list[str] = Field(default_factory=lambda: list(FAULT_KINDS))
    retry_after_s: float = Field(1.0, ge=0)
    hang_s: float = Field(3600.0, ge=0)
    drip_s: float = Field(1.0, gt=0, description="seconds between the bytes of a dripped body")
    first_tries: int = Field(0, ge=0, description="fault the first N arrivals of every distinct request (tests), on top of `rate`")
    in_turn: bool = Field(False, description="serve the kinds in turn, not drawn at random: a test that must see "
                                             "every kind sees it once len(kinds) faults were served")

    @field_validator("kinds")
    @classmethod
    def _known(cls, v: list[str]) -> list[str]:
        bad = [k for k in v if k not in FAULT_KINDS + SLOW_FAULTS]
        if bad or not v:
            raise ValueError(f"fault kinds must be a non-empty subset of {FAULT_KINDS + SLOW_FAULTS}, got {v}")
        return v


class ServerConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")

    latency_s: float = Field(0.0, ge=0)
    latency_jitter_s: float = Field(0.0, ge=0)
    seed: int = 0
    faults: Faults = Faults()
    require_key_env: str | None = None  # when set, requests must carry this env var's key
    record_bodies: int = Field(0, ge=0)
    log_path: str | None = None
    # A self-hosted server's own limits on Chat Completions (as vLLM enforces them; None: none):
    max_images_per_prompt: int | None = Field(None, ge=0, description="vLLM --limit-mm-per-prompt (images)")
    max_model_len: int | None = Field(None, ge=1, description="vLLM --max-model-len: prompt + max_tokens")


def _rng(*keys: Any):
    return seeded_rng("model-server", *keys)


_URLSAFE_TO_STD = str.maketrans("-_", "+/")


def _b64_png_tokens(data: str) -> int:
    # Either base64 alphabet: the Gemini API (proto3 JSON bytes) accepts both, and
    # google-genai sends the URL-safe one.
    try:
        head = base64.b64decode(data[:44].translate(_URLSAFE_TO_STD))
    except ValueError:
        return 258
    return image_tokens(head + b"\0" * 24)


class ApiError(Exception):
    """An error answer. Each format writes it in its provider's own shape; `code` is the
    provider's machine-readable code (OpenAI `error.code`, Gemini ErrorInfo `reason`)."""

    def __init__(self, status: int, message: str, *, code: str | None = None, param: str | None = None,
                 retry_after_s: float | None = None) -> None:
        super().__init__(message)
        self.status, self.message, self.code, self.param, self.retry_after_s = status, message, code, param, retry_after_s


class BadRequest(ApiError):
    def __init__(self, message: str, *, param: str | None = None) -> None:
        super().__init__(400, message, param=param)


def _retry_after_header(e: ApiError) -> dict[str, str]:
    return {} if e.retry_after_s is None else {"Retry-After": f"{e.retry_after_s:g}"}


_CREDENTIAL_HEADER = re.compile(r"key|auth|token|secret|cookie", re.IGNORECASE)


def _masked(name: str, value: str) -> str:
    """A header value fit to record: credentials keep only their scheme ("Bearer ***")."""
    if not _CREDENTIAL_HEADER.search(name):
        return value
    scheme, _, rest = value.partition(" ")
    return f"{scheme} ***" if rest else "***"


def _request_id(prefix: str = "req_") -> str:
    return prefix + secrets.token_hex(12)


# --- the three wire formats --------------------------------------------------------------
#
# Each format: normalize (the body as the provider reads it), validate, prompt_tokens,
# reply, error (body + headers in the provider's documented error shape), key (the
# credential as the provider reads it) and auth_error. tests/test_sdk_conformance.py
# checks replies and errors against the providers' official SDKs.


class OpenAIFormat:
    """Errors: {"error": {"message", "type", "param", "code"}}; every response carries
    `x-request-id`; 429 carries Retry-After."""

    name = "openai"
    request_id_header = "x-request-id"

    @staticmethod
    def normalize(body: Any) -> Any:
        return body

    @staticmethod
    def validate(body: Any, request: web.Request) -> None:
        if not isinstance(body, dict) or not isinstance(body.get("model"), str):
            raise BadRequest("you must provide a model parameter", param="model")
        msgs = body.get("messages")
        if not isinstance(msgs, list) or not msgs:
            raise BadRequest("'messages' must be a non-empty array", param="messages")
        for m in msgs:
            if not isinstance(m, dict) or m.get("role") not in ("system", "developer", "user", "assistant", "tool"):
                raise BadRequest("each message needs a valid 'role'", param="messages")
            c = m.get("content")
            if isinstance(c, list):
                for p in c:
                    if not isinstance(p, dict) or p.get("type") not in ("text", "image_url"):
                        raise BadRequest("content parts must be of type text or image_url", param="messages")
                    if p["type"] == "image_url" and not str((p.get("image_url") or {}).get("url", "")).startswith(
                        ("data:image/", "http")
                    ):
                        raise BadRequest("image_url.url must be a data URL or http(s) URL", param="messages")
            elif not isinstance(c, str):
                raise BadRequest("'content' must be a string or an array of parts", param="messages")
        if body.get("stream"):
            raise BadRequest("streaming is not supported by this server", param="stream")
        t = body.get("temperature")
        if t is not None and not (isinstance(t, (int, float)) and 0 <= t <= 2):
            raise BadRequest("'temperature' must be between 0 and 2", param="temperature")

    @staticmethod
    def prompt_tokens(body: dict) -> int:
        n = 0
        for m in body["messages"]:
            c = m.get("content")
            if isinstance(c, str):
                n += text_tokens(c)
            else:
                for p in c:
                    if p["type"] == "text":
                        n += text_tokens(p.get("text", ""))
                    else:
                        n += _b64_png_tokens(p["image_url"]["url"].partition(",")[2])
        return n

    @staticmethod
    def reply(body: dict, text: str | None, tin: int, tout: int) -> dict:
        choices = (
            []
            if text is None
            else [{"index": 0, "message": {"role": "assistant", "content": text}, "finish_reason": "stop", "logprobs": None}]
        )
        return {
            "id": "chatcmpl-" + secrets.token_hex(12),
            "object": "chat.completion",
            "created": int(time.time()),
            "model": body.get("model", ""),
            "choices": choices,
            "usage": {"prompt_tokens": tin, "completion_tokens": tout, "total_tokens": tin + tout},
        }

    # error.type as OpenAI sends it: a rate limit names the limit hit ("requests" or
    # "tokens") and carries code "rate_limit_exceeded".
    ERROR_TYPES = {400: "invalid_request_error", 401: "invalid_request_error", 404: "invalid_request_error", 429: "requests"}
    ERROR_CODES = {429: "rate_limit_exceeded"}

    @classmethod
    def error(cls, e: ApiError, request_id: str) -> tuple[dict, dict[str, str]]:
        kind = cls.ERROR_TYPES.get(e.status, "server_error" if e.status >= 500 else "invalid_request_error")
        body = {"error": {"message": e.message, "type": kind, "param": e.param, "code": e.code or cls.ERROR_CODES.get(e.status)}}
        return body, _retry_after_header(e)

    @staticmethod
    def key(request: web.Request) -> str | None:
        auth = request.headers.get("Authorization", "")
        return auth[7:] if auth.startswith("Bearer ") else None

    @staticmethod
    def auth_error(missing: bool) -> ApiError:
        if missing:
            return ApiError(401, "You didn't provide an API key. Provide it in an Authorization header using Bearer auth "
                                 "(Authorization: Bearer YOUR_KEY).")
        return ApiError(401, "Incorrect API key provided.", code="invalid_api_key")


def check_server_limits(body: dict, config: ServerConfig) -> None:
    """A Chat Completions request against a self-hosted server's limits, refused with a 400
    as vLLM refuses it: more images than --limit-mm-per-prompt, or a prompt whose tokens plus
    max_tokens exceed --max-model-len (tokens counted as `OpenAIFormat.prompt_tokens` does)."""
    if config.max_images_per_prompt is not None:
        images = sum(isinstance(m.get("content"), list) and sum(p["type"] == "image_url" for p in m["content"])
                     for m in body["messages"])
        if images > config.max_images_per_prompt:
            raise BadRequest(f"At most {config.max_images_per_prompt} image(s) may be provided in one prompt; "
                             f"this one has {images} (--limit-mm-per-prompt)", param="messages")
    if config.max_model_len is not None:
        prompt = OpenAIFormat.prompt_tokens(body)
        reply = body.get("max_completion_tokens") or body.get("max_tokens") or 0
        if prompt + reply > config.max_model_len:
            raise BadRequest(f"This model's maximum context length is {config.max_model_len} tokens. However, you "
                             f"requested {prompt + reply} tokens ({prompt} in the messages, {reply} in the "
                             "completion). Please reduce the length of the messages or completion.", param="messages")


# The Anthropic API versions this server knows.
ANTHROPIC_VERSIONS = ("2023-06-01", ANTHROPIC_NO_SAMPLING_FROM)


class AnthropicFormat:
    """Errors: {"type": "error", "error": {"type", "message"}, "request_id"}; every
    response carries the same id in a `request-id` header; 429 carries Retry-After. The
    key comes in `x-api-key` or, as the 2.x SDKs send it, `Authorization: Bearer`."""

    name = "anthropic"
    request_id_header = "request-id"

    @staticmethod
    def normalize(body: Any) -> Any:
        return body

    @staticmethod
    def validate(body: Any, request: web.Request) -> None:
        version = request.headers.get("anthropic-version")
        if not version:
            raise BadRequest("anthropic-version: header is required")
        if version not in ANTHROPIC_VERSIONS:
            raise BadRequest(f"anthropic-version: unknown version {version!r}")
        if not isinstance(body, dict) or not isinstance(body.get("model"), str):
            raise BadRequest("model: Field required")
        if not isinstance(body.get("max_tokens"), int) or body["max_tokens"] < 1:
            raise BadRequest("max_tokens: Field required")
        msgs = body.get("messages")
        if not isinstance(msgs, list) or not msgs:
            raise BadRequest("messages: Field required")
        for m in msgs:
            if not isinstance(m, dict) or m.get("role") not in ("user", "assistant"):
                raise BadRequest("messages: roles must be 'user' or 'assistant' (system is a top-level field)")
            c = m.get("content")
            if isinstance(c, list):
                for b in c:
                    if not isinstance(b, dict) or b.get("type") not in ("text", "image"):
                        raise BadRequest("content blocks must be of type text or image")
                    if b["type"] == "image":
                        src = b.get("source") or {}
                        if src.get("type") != "base64" or src.get("media_type") not in (
                            "image/png", "image/jpeg", "image/gif", "image/webp"
                        ) or not isinstance(src.get("data"), str):
                            raise BadRequest("image source must be {type: base64, media_type, data}")
            elif not isinstance(c, str):
                raise BadRequest("content must be a string or an array of blocks")
        if body.get("stream"):
            raise BadRequest("stream: streaming is not supported by this server")
        if version >= ANTHROPIC_NO_SAMPLING_FROM:
            for name in ("temperature", "top_p", "top_k"):
                if name in body:
                    raise BadRequest(f"{name}: Extra inputs are not permitted")
        t = body.get("temperature")
        if t is not None and not (isinstance(t, (int, float)) and 0 <= t <= 1):
            raise BadRequest("temperature: must be between 0 and 1")

    @staticmethod
    def prompt_tokens(body: dict) -> int:
        n = text_tokens(body["system"]) if isinstance(body.get("system"), str) else 0
        for m in body["messages"]:
            c = m["content"]
            if isinstance(c, str):
                n += text_tokens(c)
            else:
                for b in c:
                    n += text_tokens(b.get("text", "")) if b["type"] == "text" else _b64_png_tokens(b["source"]["data"])
        return n

    @staticmethod
    def reply(body: dict, text: str | None, tin: int, tout: int) -> dict:
        return {
            "id": "msg_" + secrets.token_hex(12),
            "type": "message",
            "role": "assistant",
            "model": body.get("model", ""),
            "content": [] if text is None else [{"type": "text", "text": text}],
            "stop_reason": "end_turn",
            "stop_sequence": None,
            "usage": {"input_tokens": tin, "output_tokens": tout},
        }

    ERROR_TYPES = {400: "invalid_request_error", 401: "authentication_error", 403: "permission_error",
                   404: "not_found_error", 429: "rate_limit_error", 500: "api_error", 504: "timeout_error",
                   529: "overloaded_error"}

    @classmethod
    def error(cls, e: ApiError, request_id: str) -> tuple[dict, dict[str, str]]:
        kind = cls.ERROR_TYPES.get(e.status, "api_error" if e.status >= 500 else "invalid_request_error")
        return {"type": "error", "error": {"type": kind, "message": e.message}, "request_id": request_id}, _retry_after_header(e)

    @staticmethod
    def key(request: web.Request) -> str | None:
        if "x-api-key" in request.headers:  # the API reads x-api-key first when both are sent
            return request.headers["x-api-key"]
        return OpenAIFormat.key(request)

    @staticmethod
    def auth_error(missing: bool) -> ApiError:
        return ApiError(401, "x-api-key header is required" if missing else "invalid x-api-key")


def _camel(key: str) -> str:
    head, *rest = key.split("_")
    return head + "".join(w[:1].upper() + w[1:] for w in rest)


def _camel_keys(value: Any) -> Any:
    if isinstance(value, dict):
        return {_camel(k): _camel_keys(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_camel_keys(v) for v in value]
    return value


def _duration(seconds: float) -> str:
    """A google.protobuf.Duration in JSON ("22s", "0.250s")."""
    return f"{seconds:.0f}s" if seconds == int(seconds) else f"{seconds:.3f}s"


class GeminiFormat:
    """Errors: {"error": {"code", "message", "status", "details"}} (google.rpc.Status as
    HTTP JSON). A 429 says how long to wait in a google.rpc.RetryInfo detail, not in a
    header; a wrong key is a 400 with ErrorInfo reason API_KEY_INVALID and a missing one
    a 403, as the Gemini API answers them. Field names may come in lowerCamelCase or
    snake_case (proto3 JSON accepts both) and bytes in either base64 alphabet."""

    name = "gemini"
    request_id_header = None

    @staticmethod
    def normalize(body: Any) -> Any:
        return _camel_keys(body)

    @staticmethod
    def validate(body: Any, request: web.Request) -> None:
        if not request.match_info.get("model", "").endswith(":generateContent"):
            raise ApiError(404, f"method not found: {request.path} (only models/{{model}}:generateContent is served)")
        if not isinstance(body, dict) or not isinstance(body.get("contents"), list) or not body["contents"]:
            raise BadRequest("* GenerateContentRequest.contents: contents is not specified")
        for c in body["contents"]:
            if not isinstance(c, dict) or c.get("role") not in ("user", "model") or not isinstance(c.get("parts"), list):
                raise BadRequest("each content needs role user|model and parts")
            for p in c["parts"]:
                if not isinstance(p, dict) or not ("text" in p or "inlineData" in p):
                    raise BadRequest("parts must carry text or inlineData")
                if "inlineData" in p:
                    d = p["inlineData"]
                    if not isinstance(d, dict) or not str(d.get("mimeType", "")).startswith("image/") or not isinstance(d.get("data"), str):
                        raise BadRequest("inlineData needs mimeType and base64 data")

    @staticmethod
    def prompt_tokens(body: dict) -> int:
        n = sum(text_tokens(p.get("text", "")) for p in (body.get("systemInstruction") or {}).get("parts", []))
        for c in body["contents"]:
            for p in c["parts"]:
                n += text_tokens(p["text"]) if "text" in p else _b64_png_tokens(p["inlineData"]["data"])
        return n

    @staticmethod
    def reply(body: dict, text: str | None, tin: int, tout: int) -> dict:
        candidates = (
            []
            if text is None
            else [{"content": {"role": "model", "parts": [{"text": text}]}, "finishReason": "STOP", "index": 0}]
        )
        return {
            "candidates": candidates,
            "usageMetadata": {"promptTokenCount": tin, "candidatesTokenCount": tout, "totalTokenCount": tin + tout},
            "modelVersion": "deepphy-mock",
            "responseId": secrets.token_urlsafe(16),
        }

    STATUSES = {400: "INVALID_ARGUMENT", 401: "UNAUTHENTICATED", 403: "PERMISSION_DENIED", 404: "NOT_FOUND",
                429: "RESOURCE_EXHAUSTED", 499: "CANCELLED", 500: "INTERNAL", 503: "UNAVAILABLE", 504: "DEADLINE_EXCEEDED"}

    @classmethod
    def error(cls, e: ApiError, request_id: str) -> tuple[dict, dict[str, str]]:
        details: list[dict] = []
        if e.code:
            details.append({"@type": "type.googleapis.com/google.rpc.ErrorInfo", "reason": e.code, "domain": "googleapis.com",
                            "metadata": {"service": "generativelanguage.googleapis.com"}})
        if e.retry_after_s is not None:
            details.append({"@type": "type.googleapis.com/google.rpc.RetryInfo", "retryDelay": _duration(e.retry_after_s)})
        status = cls.STATUSES.get(e.status, "INTERNAL" if e.status >= 500 else "UNKNOWN")
        error: dict[str, Any] = {"code": e.status, "message": e.message, "status": status}
        if details:
            error["details"] = details
        return {"error": error}, {}

    @staticmethod
    def key(request: web.Request) -> str | None:
        return request.headers.get("x-goog-api-key") or request.query.get("key")

    @staticmethod
    def auth_error(missing: bool) -> ApiError:
        if missing:
            return ApiError(403, "Method doesn't allow unregistered callers (callers without established identity). "
                                 "Please use API Key or other form of API consumer identity to call this API.")
        return ApiError(400, "API key not valid. Please pass a valid API key.", code="API_KEY_INVALID")


# --- the server ------------------------------------------------------------------------------


class MockServer:
    def __init__(self, config: ServerConfig | None = None) -> None:
        self.config = config or ServerConfig()
        self._runner: web.AppRunner | None = None
        self.port: int | None = None
        self._reset()
        app = web.Application(client_max_size=256 * 1024**2)
        for path, fmt in (
            ("/v1/chat/completions", OpenAIFormat),
            ("/chat/completions", OpenAIFormat),
            ("/v1/messages", AnthropicFormat),
            ("/v1beta/models/{model}", GeminiFormat),
            ("/v1/models/{model}", GeminiFormat),
        ):
            app.router.add_post(path, self._handler(fmt))
        app.router.add_get("/stats", self._stats)
        app.router.add_get("/health", self._health)
        app.router.add_get("/admin/bodies", self._bodies)
        app.router.add_post("/admin/config", self._configure)
        app.router.add_post("/admin/reset", self._reset_route)
        self.app = app

    def _reset(self) -> None:
        self.arrivals: list[float] = []
        self.seen: Counter[str] = Counter()
        self.faults: Counter[str] = Counter()
        self.faults_chosen = 0  # for `in_turn`: counted when chosen (answers interleave)
        self.statuses: Counter[int] = Counter()
        self.in_flight = 0
        self.max_in_flight = 0
        self.bodies: deque[dict] = deque(maxlen=max(self.config.record_bodies, 1))

    async def start(self, host: str = LOOPBACK_HOST, port: int = 0) -> int:
        self._runner = web.AppRunner(self.app, handler_cancellation=True, max_field_size=1024**2, access_log=None)
        await self._runner.setup()
        site = web.TCPSite(self._runner, host, port, backlog=1024)
        await site.start()
        self.port = site._server.sockets[0].getsockname()[1]  # type: ignore[union-attr]
        return self.port

    async def stop(self) -> None:
        if self._runner is not None:
            await self._runner.cleanup()
            self._runner = None

    def stats(self, arrivals: bool = True) -> dict:
        out = {
            "requests": len(self.arrivals),
            "faults": dict(self.faults),
            "status": {str(k): v for k, v in self.statuses.items()},
            "in_flight": self.in_flight,
            "max_in_flight": self.max_in_flight,
        }
        if arrivals:
            out["arrivals"] = list(self.arrivals)
        return out

    async def _stats(self, request: web.Request) -> web.Response:
        return web.json_response(self.stats(request.query.get("arrivals", "1") != "0"))

    async def _health(self, request: web.Request) -> web.Response:
        return web.json_response({"ok": True})

    async def _bodies(self, request: web.Request) -> web.Response:
        return web.json_response(list(self.bodies))

    async def _configure(self, request: web.Request) -> web.Response:
        patch = await request.json()
        merged = self.config.model_dump()
        for k, v in patch.items():
            merged[k] = {**merged[k], **v} if isinstance(v, dict) and isinstance(merged.get(k), dict) else v
        try:
            self.config = ServerConfig.model_validate(merged)
        except ValueError as e:
            return web.json_response({"error": str(e)}, status=400)
        return web.json_response(self.config.model_dump())

    async def _reset_route(self, request: web.Request) -> web.Response:
        self._reset()
        return web.json_response({"ok": True})

    async def _drip(self, request: web.Request, payload: dict, headers: dict[str, str]) -> web.StreamResponse:
        data = json.dumps(payload).encode()
        resp = web.StreamResponse(headers={**headers, "Content-Type": "application/json",
                                           "Content-Length": str(len(data))})
        await resp.prepare(request)
        for i in range(len(data)):
            await resp.write(data[i:i + 1])
            await asyncio.sleep(self.config.faults.drip_s)
        await resp.write_eof()
        return resp

    def _handler(self, fmt):
        async def handle(request: web.Request) -> web.StreamResponse:
            arrived = time.time()
            self.arrivals.append(arrived)
            self.in_flight += 1
            self.max_in_flight = max(self.max_in_flight, self.in_flight)
            fault = None
            status = 0
            try:
                resp, fault = await self._answer(fmt, request)
                status = resp.status
                return resp
            finally:
                self.in_flight -= 1
                self.statuses[status] += 1  # 0: the client went away first (e.g. a hang)
                if self.config.log_path:
                    with open(self.config.log_path, "a") as f:
                        f.write(json.dumps({"t": arrived, "api": fmt.name, "fault": fault, "status": status}) + "\n")

        return handle

    async def _answer(self, fmt, request: web.Request) -> tuple[web.StreamResponse, str | None]:
        cfg = self.config
        raw = await request.read()
        ctx_header = request.headers.get(CONTEXT_HEADER, "")
        digest = hashlib.sha256(raw + b"\0" + ctx_header.encode() + request.path.encode()).hexdigest()
        nth = self.seen[digest]
        self.seen[digest] += 1
        rng = _rng(cfg.seed, digest, nth)
        fault = None
        if nth < cfg.faults.first_tries or rng.random() < cfg.faults.rate:
            if cfg.faults.in_turn:
                fault = cfg.faults.kinds[self.faults_chosen % len(cfg.faults.kinds)]
            else:
                fault = cfg.faults.kinds[int(rng.integers(len(cfg.faults.kinds)))]
            self.faults_chosen += 1
        delay = cfg.latency_s + (rng.random() * cfg.latency_jitter_s if cfg.latency_jitter_s else 0.0)
        if cfg.record_bodies:
            try:
                body_json = json.loads(raw)
            except ValueError:
                body_json = None
            headers = {k: _masked(k, v) for k, v in request.headers.items()}
            self.bodies.append({"path": request.path, "headers": headers, "body": body_json})
        request_id = _request_id()
        id_header = {fmt.request_id_header: request_id} if fmt.request_id_header else {}

        def err(e: ApiError) -> web.Response:
            body, headers = fmt.error(e, request_id)
            return web.json_response(body, status=e.status, headers={**id_header, **headers})

        if cfg.require_key_env:
            expected = os.environ.get(cfg.require_key_env, "")
            given = fmt.key(request)
            if not expected or not secrets.compare_digest(given or "", expected):
                return err(fmt.auth_error(missing=not given)), None
        try:
            body = fmt.normalize(json.loads(raw))
            fmt.validate(body, request)
            if fmt is OpenAIFormat:
                check_server_limits(body, cfg)
        except ApiError as e:
            return err(e), None
        except ValueError:
            return err(BadRequest("request body is not valid JSON")), None
        if fault:
            self.faults[fault] += 1  # counted when served (a hang is cut short by the client)
        if delay:
            await asyncio.sleep(delay)
        if fault == "429":
            return err(ApiError(429, "rate limit reached for requests (injected)", retry_after_s=cfg.faults.retry_after_s)), fault
        if fault == "500":
            return err(ApiError(500, "internal server error (injected)")), fault
        if fault == "hang":
            await asyncio.sleep(cfg.faults.hang_s)
            return err(ApiError(504, "gateway timeout (injected hang)")), fault
        if not ctx_header:
            return err(BadRequest(f"this server answers with the MOCK policy and needs the {CONTEXT_HEADER} header "
                                  "(set send_context: true in the model config)")), fault
        try:
            ctx = decode_context(ctx_header)
        except Exception:
            return err(BadRequest(f"bad {CONTEXT_HEADER} header")), fault
        if fault == "malformed":
            return web.Response(text='{"id": "x", "choices": [{"message": {"content": "', content_type="application/json",
                                headers=id_header), fault
        tin = fmt.prompt_tokens(body)
        if fault == "empty":
            return web.json_response(fmt.reply(body, None, tin, 0), headers=id_header), fault
        if fault == "prose":
            text = PROSE_REPLY
        else:
            from deepphy.agents import mock_text  # the environments' baselines: only a MOCK fault needs them

            text = mock_text(ctx)
        if fault == "drip":
            return await self._drip(request, fmt.reply(body, text, tin, text_tokens(text)), id_header), fault
        return web.json_response(fmt.reply(body, text, tin, text_tokens(text)), headers=id_header), fault


# --- running it ------------------------------------------------------------------------------


class ServerThread:
    """A MockServer on its own event loop in a daemon thread (for tests and scripts)."""

    def __init__(self, config: ServerConfig | None = None, host: str = LOOPBACK_HOST, port: int = 0) -> None:
        self.server = MockServer(config)
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True, name="deepphy-model-server")
        self._thread.start()
        self.port = self._call(self.server.start(host, port))
        self.host = host

    def _call(self, coro, timeout: float = 30.0):
        return asyncio.run_coroutine_threadsafe(coro, self._loop).result(timeout)

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def stats(self, arrivals: bool = True) -> dict:
        async def get():
            return self.server.stats(arrivals)

        return self._call(get())

    def configure(self, **patch: Any) -> None:
        async def set_():
            merged = self.server.config.model_dump()
            for k, v in patch.items():
                merged[k] = {**merged[k], **v} if isinstance(v, dict) and isinstance(merged.get(k), dict) else v
            self.server.config = ServerConfig.model_validate(merged)

        self._call(set_())

    def reset(self) -> None:
        async def r():
            self.server._reset()

        self._call(r())

    def bodies(self) -> list[dict]:
        async def b():
            return list(self.server.bodies)

        return self._call(b())

    def stop(self) -> None:
        try:
            self._call(self.server.stop())
        finally:
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(10)

    def __enter__(self) -> "ServerThread":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def spawn(*args: str, timeout_s: float = 60.0):
    """Start `python -m deepphy.testing.model_server --port 0 ARGS` in a subprocess.
    Returns (Popen, base URL); the caller terminates it. On Linux the server also ends when
    the thread that spawned it does (the caller killed, say), so none is left behind."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "deepphy.testing.model_server", "--port", "0", *args],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
        env={**os.environ, "PYGAME_HIDE_SUPPORT_PROMPT": "1"},
        preexec_fn=_end_with_parent if sys.platform.startswith("linux") else None,
    )
    deadline = time.time() + timeout_s
    while time.time() < deadline:
        line = proc.stdout.readline()  # type: ignore[union-attr]
        if "listening on " in line:
            return proc, line.strip().rsplit(" ", 1)[-1]
        if not line and proc.poll() is not None:
            break
    proc.kill()
    raise RuntimeError("the model server did not start")


def _end_with_parent() -> None:
    """In the child, before exec: SIGTERM when the parent (thread) ends (prctl PR_SET_PDEATHSIG)."""
    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m deepphy.testing.model_server", description=__doc__.split("\n\n")[0])
    served, faulted = ServerConfig.model_fields, Faults.model_fields  # the flags' defaults are the models' (said once)
    ap.add_argument("--host", default=LOOPBACK_HOST, help="interface to listen on; default %(default)s")
    ap.add_argument("--port", type=int, default=DEFAULT_PORT, help="default %(default)s; 0: any free port (printed)")
    ap.add_argument("--latency", type=float, default=served["latency_s"].default, help="seconds before each answer")
    ap.add_argument("--latency-jitter", type=float, default=served["latency_jitter_s"].default,
                    help="extra uniform 0..J seconds")
    ap.add_argument("--seed", type=int, default=served["seed"].default)
    ap.add_argument("--fault-rate", type=float, default=faulted["rate"].default)
    ap.add_argument("--faults", default=",".join(FAULT_KINDS),
                    help=f"comma list of {','.join(FAULT_KINDS + SLOW_FAULTS)}")
    ap.add_argument("--retry-after", type=float, default=faulted["retry_after_s"].default,
                    help="Retry-After seconds sent with 429")
    ap.add_argument("--hang", type=float, default=faulted["hang_s"].default,
                    help="seconds a 'hang' fault holds the request")
    ap.add_argument("--drip", type=float, default=faulted["drip_s"].default,
                    help="seconds between the bytes of a 'drip' fault's body")
    ap.add_argument("--first-tries", type=int, default=faulted["first_tries"].default,
                    help="fault the first N arrivals of every distinct request")
    ap.add_argument("--require-key-env", default=None, help="require the key held in this env var")
    ap.add_argument("--record-bodies", type=int, default=served["record_bodies"].default,
                    help="keep the last N request bodies (GET /admin/bodies)")
    ap.add_argument("--log", default=None, help="append one JSON line per request (arrival time, fault, status)")
    ap.add_argument("--limit-mm-per-prompt", type=int, default=None, metavar="N",
                    help="refuse Chat Completions requests with more than N images, as vLLM does")
    ap.add_argument("--max-model-len", type=int, default=None, metavar="TOKENS",
                    help="refuse Chat Completions requests whose prompt + max_tokens exceed this, as vLLM does")
    a = ap.parse_args(argv)
    config = ServerConfig(
        latency_s=a.latency,
        latency_jitter_s=a.latency_jitter,
        seed=a.seed,
        faults=Faults(rate=a.fault_rate, kinds=[k for k in a.faults.split(",") if k], retry_after_s=a.retry_after, hang_s=a.hang, drip_s=a.drip,
                      first_tries=a.first_tries),
        require_key_env=a.require_key_env,
        record_bodies=a.record_bodies,
        log_path=a.log,
        max_images_per_prompt=a.limit_mm_per_prompt,
        max_model_len=a.max_model_len,
    )

    async def run() -> None:
        server = MockServer(config)
        port = await server.start(a.host, a.port)
        print(f"deepphy model server listening on http://{a.host}:{port}", flush=True)
        try:
            await asyncio.Event().wait()
        finally:
            await server.stop()

    try:
        asyncio.run(run())
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    main(sys.argv[1:])
