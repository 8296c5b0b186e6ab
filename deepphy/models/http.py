"""The HTTP client shared by all providers: limiter, retries, deadlines, usage and cost, secrecy.

A provider subclass says only how to build its request and read its response
(deepphy/models/clients.py, or a plug-in's). Everything else is here:
- one aiohttp session per event loop; the connection pool is sized by max_concurrent
  (unbounded when no limit is set);
- every HTTP try takes a grant from the endpoint's limiter and returns it with the tokens
  actually used. The limiter is injected: the model worker passes the cluster-wide Ray
  limiter; by default a client limits itself in-process (`LocalLimiter`);
- deadlines (config `timeouts`): every try is bounded by its connection, its first byte
  (the status line), its body (from the status line) and its whole, and by what is left of
  the request's total, so a request never takes longer than `timeouts.deadline_s`, retries
  and waits included; deadlines are on the event loop's clock, as asyncio's timeouts are;
- a response body is read up to `MAX_BODY_BYTES` and no further (a larger one is an
  unusable answer, like malformed JSON);
- retries with exponential backoff and jitter on 429, 408, 409, 5xx, timeouts,
  connection errors and unusable 200s (malformed JSON, no choices, too large);
  `Retry-After` / `retry-after-ms` (Gemini: RetryInfo in the error body) is honoured up to
  max_retry_after_s: an endpoint that asks for longer fails the request at once; at most
  max_retries; then `ModelError(retries=..., kind=...)`. A refused key (401, 403, Gemini's
  API_KEY_INVALID) is `AccessDenied` and any other 4xx `RequestRejected` (vLLM's 400 for
  too many images or too long a prompt): the same request would fail again, so both stop
  the run with one line;
- `activity()`: what the requests are waiting for now (the rate limit; a retry, how long
  and why; an answer that is slow to come), for the progress line;
- the key is read from the environment, held as a SecretStr, never pickled, never in
  repr, and scrubbed from every error text.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import random
from collections import Counter
from typing import Any

import aiohttp
from pydantic import SecretStr

from deepphy.chat import Message
from deepphy.models.base import (
    AccessDenied, ModelClient, ModelError, ModelRequest, ModelResponse, RequestContext, RequestRejected, Usage,
)
from deepphy.models.config import ModelConfig
from deepphy.models.limiter import Limiter, LocalLimiter
from deepphy.models.wire import (
    CONTEXT_HEADER, encode_context, estimate_input_tokens, input_budget, limit_images, merge_body,
    parse_retry_after,
)
from deepphy.seeding import seeded_rng

RETRYABLE_STATUS = {408, 409, 429}  # plus every 5xx (Anthropic's 529 "overloaded" included)
DENIED_STATUS = {401, 403}  # and Gemini's 400 with reason API_KEY_INVALID
# A reply is cut to 32,768 characters (deepphy.envs.parsing) and a provider's JSON around it
# is a few kB: a body past this is no answer, and reading it whole first (a 50 MB body was)
# costs the worker its memory.
MAX_BODY_BYTES = 8 * 1024**2
SLOW_ANSWER_S = 30.0  # a try waiting longer than this for its answer is named on the progress line


class EmptyReply(ValueError):
    """A 200 response with no answer in it (no choices / candidates / content)."""


class _Failure(Exception):
    def __init__(self, kind: str, message: str, retryable: bool, retry_after: float | None = None) -> None:
        super().__init__(message)
        self.kind, self.message, self.retryable, self.retry_after = kind, message, retryable, retry_after


def request_seed(ctx: RequestContext) -> int:
    """A per-request seed for providers that take one: stable for a (seed, task, run, attempt, step)."""
    return int(seeded_rng("request-seed", ctx.seed, ctx.env, ctx.task_id, ctx.run, ctx.attempt, ctx.step).integers(2**31 - 1))


class HTTPModelClient(ModelClient):
    """Base of the provider clients. `limiter`: the endpoint's shared `Limiter`; None means
    an in-process one (or none at all when the config sets no limits)."""

    def __init__(self, config: ModelConfig, limiter: Limiter | None = None) -> None:
        self.config = config
        self.name = config.name
        key = config.api_key()
        self._key = SecretStr(key) if key else None
        if limiter is None and config.rate_limits.enabled:
            limiter = LocalLimiter(config.rate_limits)
        self._limiter = limiter
        self._session: aiohttp.ClientSession | None = None
        self._session_loop: asyncio.AbstractEventLoop | None = None
        self._rng = random.Random()
        # What the requests in flight are doing now, for `activity()` (times on the loop's clock):
        self._rate_limited = 0  # waiting for the limiter
        self._retrying: dict[int, tuple[float, str]] = {}  # request -> (end of its back-off, why)
        self._trying: dict[int, float] = {}  # request -> when its current try was sent
        self._ids = itertools.count()

    # --- what a provider supplies -------------------------------------------------------

    def url(self) -> str:
        raise NotImplementedError

    def auth_headers(self, key: str) -> dict[str, str]:
        raise NotImplementedError

    def static_headers(self) -> dict[str, str]:
        return {}

    def build_body(self, request: ModelRequest, messages: list[Message], max_tokens: int) -> dict[str, Any]:
        raise NotImplementedError

    def parse(self, data: Any) -> tuple[str, int | None, int | None]:
        """(text, input tokens, output tokens); raises EmptyReply, or KeyError/TypeError if malformed."""
        raise NotImplementedError

    # --- secrecy --------------------------------------------------------------------------

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, model={self.config.model!r}, base_url={self.config.resolved_base_url!r})"

    __str__ = __repr__

    def __reduce__(self):
        # Never pickle the key (Ray would copy it into the object store): the receiving
        # process reads it from its own environment.
        return (type(self), (self.config,))

    def _redact(self, text: str) -> str:
        if self._key is not None:
            secret = self._key.get_secret_value()
            if secret:
                text = text.replace(secret, "***")
        return text

    # --- plumbing -------------------------------------------------------------------------

    def _get_session(self) -> aiohttp.ClientSession:
        loop = asyncio.get_running_loop()
        if self._session is None or self._session.closed or self._session_loop is not loop:
            t = self.config.timeouts
            self._session = aiohttp.ClientSession(
                connector=aiohttp.TCPConnector(limit=self.config.rate_limits.max_concurrent or 0),
                timeout=aiohttp.ClientTimeout(total=None, sock_connect=t.connect_s),  # the rest: _try
            )
            self._session_loop = loop
        return self._session

    async def close(self) -> None:
        if self._session is not None and not self._session.closed and self._session_loop is asyncio.get_running_loop():
            await self._session.close()
        self._session = None

    async def activity(self) -> dict[str, Any]:
        """Requests waiting now: for the rate limit; before a retry (`retry_wait_s`: the
        longest wait left, `retry_reason`: the commonest cause, e.g. "429" or "timeout"); for
        an answer longer than SLOW_ANSWER_S (`answer_wait_s`: the longest so far)."""
        now = asyncio.get_running_loop().time()
        waits = self._retrying.values()
        slow = [now - sent for sent in self._trying.values() if now - sent > SLOW_ANSWER_S]
        return {
            "rate_limited": self._rate_limited,
            "retrying": len(self._retrying),
            "retry_wait_s": max((end - now for end, _ in waits), default=0.0),
            "retry_reason": Counter(why for _, why in waits).most_common(1)[0][0] if waits else "",
            "answering_slow": len(slow),
            "answer_wait_s": max(slow, default=0.0),
        }

    def _delay(self, retry: int, retry_after: float | None) -> float:
        p = self.config.retry
        if retry_after is not None:
            return retry_after * (1 + 0.1 * self._rng.random())
        cap = min(p.max_delay_s, p.base_delay_s * 2**retry)
        return cap * (0.5 + 0.5 * self._rng.random())

    async def _try(self, session: aiohttp.ClientSession, url: str, payload: bytes, headers: dict[str, str],
                   left_s: float):
        """One try, bounded by the first byte, the body, the whole response and `left_s` of the request."""
        t = self.config.timeouts
        whole = min(t.request_s, left_s)
        first = min(t.first_byte_s or t.request_s, whole)
        loop = asyncio.get_running_loop()
        started = loop.time()
        first_cm = asyncio.timeout(first)
        body_cm = None  # the body's deadline counts from the status line
        try:
            async with asyncio.timeout(whole):
                async with first_cm:
                    resp = await session.post(url, data=payload, headers=headers)
                status_at, body_cm = loop.time(), asyncio.timeout(t.body_s)
                async with resp, body_cm:
                    raw = await _read_capped(resp)
                    status, rheaders = resp.status, resp.headers
        except TimeoutError:
            if body_cm is not None and body_cm.expired():
                what = f"whole body within {t.body_s:g} s of the status line ({status_at - started:.3g} s after sending)"
            else:
                what = f"{'first byte' if first_cm.expired() else 'whole response'} within {loop.time() - started:.3g} s"
            raise _Failure("timeout", f"no {what}", True) from None
        except aiohttp.ClientError as e:
            raise _Failure("connection", f"connection error: {type(e).__name__}: {self._redact(str(e))[:200]}", True) from None
        if status != 200:
            snippet = self._redact(_said(raw))
            if status in DENIED_STATUS or (status == 400 and b"API_KEY_INVALID" in raw):
                raise _Failure("denied", f"HTTP {status}: {snippet}", False)
            if 400 <= status < 500 and status not in RETRYABLE_STATUS:
                raise _Failure("rejected", f"HTTP {status}: {snippet}", False)
            retryable = status in RETRYABLE_STATUS or status >= 500
            raise _Failure(f"http_{status}", f"HTTP {status}: {snippet}", retryable, parse_retry_after(rheaders, body=raw))
        try:
            data = json.loads(raw)
        except ValueError:
            raise _Failure("malformed", "response body is not valid JSON", True) from None
        try:
            return self.parse(data)
        except EmptyReply as e:
            raise _Failure("empty", f"empty reply: {self._redact(str(e))}", True) from None
        except (KeyError, TypeError, IndexError, AttributeError):
            raise _Failure("malformed", "response JSON lacks the expected fields", True) from None

    # --- the call -------------------------------------------------------------------------

    async def complete(self, request: ModelRequest) -> ModelResponse:
        cfg = self.config
        max_tokens = cfg.max_tokens or request.max_tokens
        budget = input_budget(cfg.max_context_tokens, max_tokens)
        messages, dropped = limit_images(request.messages, cfg.resolved_max_images, budget)
        body = merge_body(self.build_body(request, messages, max_tokens), cfg.extra_body)
        payload = json.dumps(body).encode()
        headers = {"Content-Type": "application/json", **self.static_headers()}
        if cfg.send_context:
            headers[CONTEXT_HEADER] = encode_context(request.context)
        if self._key is not None:
            headers.update(self.auth_headers(self._key.get_secret_value()))
        estimate_in = estimate_input_tokens(messages)
        if budget is not None and estimate_in > budget:  # the server would refuse it (vLLM: 400)
            raise ModelError(f"{self.name}: the prompt's ~{estimate_in} input tokens (every image omitted) and "
                             f"max_tokens {max_tokens} do not fit max_context_tokens {cfg.max_context_tokens}",
                             kind="context")
        limiter = self._limiter
        lease_s = cfg.timeouts.request_s + cfg.timeouts.connect_s + 30.0
        session = self._get_session()
        url = self.url()
        clock = asyncio.get_running_loop().time
        deadline = clock() + cfg.timeouts.deadline_s
        retries = 0
        me = next(self._ids)
        while True:
            grant = None
            if limiter is not None:
                self._rate_limited += 1
                try:
                    grant = await limiter.acquire(estimate_in + max_tokens, lease_s)
                finally:
                    self._rate_limited -= 1
            used = estimate_in + max_tokens
            try:
                left = deadline - clock()
                if left <= 0:
                    raise _Failure("deadline", f"no answer within the request's {cfg.timeouts.deadline_s:g} s", False)
                self._trying[me] = clock()
                try:
                    text, tin, tout = await self._try(session, url, payload, headers, left)
                finally:
                    del self._trying[me]
                tin = tin if tin is not None else estimate_in
                tout = tout if tout is not None else 0
                used = tin + tout
            except _Failure as f:
                note = f" (after {retries} retries)" if retries else ""
                if f.kind == "denied":
                    raise self._denied(f.message) from None
                if f.kind == "rejected":
                    raise self._rejected(f.message, sum(len(m.images) for m in messages)) from None
                if f.retry_after is not None and f.retry_after > cfg.retry.max_retry_after_s:
                    raise ModelError(f"{self.name}: {f.message} asks to wait {f.retry_after:g} s, longer than "
                                     f"max_retry_after_s ({cfg.retry.max_retry_after_s:g} s){note}",
                                     retries=retries, kind="retry_after") from None
                delay = self._delay(retries, f.retry_after) if f.retryable else 0.0
                if not f.retryable or retries >= cfg.retry.max_retries or clock() + delay >= deadline:
                    raise ModelError(f"{self.name}: {f.message}{note}", retries=retries, kind=f.kind) from None
                why = f.kind.removeprefix("http_")  # for the progress line: "429", "timeout", ...
            else:
                return ModelResponse(
                    text=text,
                    usage=Usage(input_tokens=tin, output_tokens=tout, cost_usd=cfg.price.cost(tin, tout)),
                    retries=retries,
                    images_dropped=dropped,
                )
            finally:
                if grant is not None:
                    await limiter.release(grant, used)
            retries += 1
            self._retrying[me] = (clock() + delay, why)
            try:
                await asyncio.sleep(delay)
            finally:
                del self._retrying[me]

    def _denied(self, message: str) -> AccessDenied:
        cfg = self.config
        key = (f"the key in ${cfg.api_key_env}" if cfg.api_key_env
               else "no key (this entry has no api_key_env)")
        return AccessDenied(f"model {self.name} at {cfg.resolved_base_url} refused {key}: {message}; "
                            "check the key and its permissions for this model", kind="denied")

    def _rejected(self, message: str, images: int) -> RequestRejected:
        cfg = self.config
        if message.startswith("HTTP 404"):
            hint = f"check base_url and the model id ({cfg.model}) of this entry"
        else:  # vLLM, SGLang and the providers answer 400 (413, 422) for these two
            hint = (f"a server answers so for more images than it takes per prompt (this one sent {images}; the "
                    f"entry's max_images is {cfg.resolved_max_images}) or a prompt longer than the model's "
                    "context: lower max_images for this entry in the models file, or serve a longer context")
        return RequestRejected(f"model {self.name} at {cfg.resolved_base_url} rejected the request: {message}; "
                               f"{hint}", kind="rejected")


def _said(raw: bytes) -> str:
    """What an error body says, in one line: the message of a provider's (or vLLM's) error
    JSON, else the body's start."""
    try:
        data = json.loads(raw)
        error = data.get("error", data) if isinstance(data, dict) else data
        said = error.get("message") or error.get("detail") if isinstance(error, dict) else None
        text = said if isinstance(said, str) else raw[:300].decode("utf-8", "replace")
    except ValueError:
        text = raw[:300].decode("utf-8", "replace")
    return " ".join(text.split())[:300]


async def _read_capped(resp: aiohttp.ClientResponse) -> bytes:
    """The body, read no further than MAX_BODY_BYTES (the connection is dropped beyond)."""
    if (resp.content_length or 0) > MAX_BODY_BYTES:
        raise _Failure("too_large", f"response body of {resp.content_length:,} bytes, over {MAX_BODY_BYTES:,}", True)
    chunks, size = [], 0
    async for chunk in resp.content.iter_any():
        size += len(chunk)
        if size > MAX_BODY_BYTES:
            raise _Failure("too_large", f"response body over {MAX_BODY_BYTES:,} bytes", True)
        chunks.append(chunk)
    return b"".join(chunks)
