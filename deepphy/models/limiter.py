"""Rate limiting of one model endpoint: requests/min, tokens/min and concurrency together.

`RateLimiterCore` is the bookkeeping (no I/O, a clock passed in); `AsyncRateLimiter`
queues callers FIFO on an asyncio loop and grants them as the core allows. The same
`AsyncRateLimiter` runs in-process (`LocalLimiter`, one process) or inside the Ray actor
of `deepphy.actors.rate_limiter` (one per endpoint, shared by every model worker).

Rules, all enforced on every grant (one grant = one HTTP try, retries included):
- requests: at most R grants in any window of W = 60 s + margin (a log of grant times),
  and grants paced at W/R apart (GCRA, `burst` may go at once after an idle spell), so
  requests are spread out rather than sent in bursts at window edges. The margin absorbs
  the jitter between the grant and the request's arrival at the provider: if that jitter
  stays below the margin, the provider never sees more than R in any 60 s window.
- tokens: at most T estimated tokens (input estimate + max_tokens) granted in any window
  W; when a request finishes, its entry is corrected to the tokens actually used. A
  single request larger than T is let through when the window is empty.
- concurrency: at most C grants held at once. A grant is a lease: one that is never
  released (its worker died) expires after `lease_s`, so slots cannot leak.
"""

from __future__ import annotations

import asyncio
import itertools
import math
import time
from collections import deque
from typing import Callable, Protocol

from pydantic import BaseModel, ConfigDict, Field

WINDOW_S = 60.0


class RateLimits(BaseModel):
    """Limits of one endpoint, enforced together by one limiter shared by all workers."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    requests_per_min: float | None = Field(None, gt=0)
    tokens_per_min: int | None = Field(None, gt=0, description="estimated input + max_tokens, corrected by actual usage")
    max_concurrent: int | None = Field(None, ge=1)
    window_margin_s: float = Field(
        1.0,
        ge=0,
        description="the 60 s window is widened by this much, so jitter between the limiter's grant "
        "and the provider's arrival cannot put more than the limit in any 60 s window",
    )
    burst: int = Field(1, ge=1, description="requests that may go at once after an idle period (pacing)")
    key: str | None = Field(None, description="limiter key; entries sharing an endpoint/account share a key")

    @property
    def enabled(self) -> bool:
        return any(v is not None for v in (self.requests_per_min, self.tokens_per_min, self.max_concurrent))


class Limiter(Protocol):
    async def acquire(self, tokens: int, lease_s: float) -> int:
        """Wait for a grant; returns its id."""

    async def release(self, grant: int, tokens: int) -> None:
        """Return a grant; `tokens` are the tokens the request actually used."""


class RateLimiterCore:
    def __init__(self, limits: RateLimits) -> None:
        self.limits = limits
        self.window = WINDOW_S + limits.window_margin_s
        rpm = limits.requests_per_min
        self.interval = self.window / rpm if rpm else 0.0
        self.slack = min(self.interval, 1.0)
        self._tat = -math.inf  # GCRA theoretical arrival time
        self._requests: deque[float] = deque()  # grant times within the window
        self._tokens: deque[list] = deque()  # [grant time, tokens, grant id] within the window
        self._token_entry: dict[int, list] = {}
        self._token_sum = 0
        self._leases: dict[int, float] = {}  # grant id -> expiry
        self._ids = itertools.count(1)
        self.granted = 0
        self.expired = 0

    def _prune(self, now: float) -> None:
        edge = now - self.window
        while self._requests and self._requests[0] <= edge:
            self._requests.popleft()
        while self._tokens and self._tokens[0][0] <= edge:
            entry = self._tokens.popleft()
            self._token_sum -= entry[1]
            self._token_entry.pop(entry[2], None)
        for gid, expiry in list(self._leases.items()):
            if expiry <= now:
                del self._leases[gid]
                self.expired += 1

    def delay(self, tokens: int, now: float) -> float:
        """Seconds until a request of `tokens` may go (0: now; inf: when a lease ends)."""
        self._prune(now)
        lim = self.limits
        wait = 0.0
        if lim.requests_per_min:
            wait = max(wait, self._tat - (lim.burst - 1) * self.interval - now)
            if len(self._requests) >= lim.requests_per_min:
                wait = max(wait, self._requests[0] + self.window - now)
        if lim.tokens_per_min and self._tokens:
            excess = self._token_sum + tokens - lim.tokens_per_min
            if excess > 0:
                freed = 0
                for t, n, _ in self._tokens:
                    freed += n
                    if freed >= excess:
                        break
                wait = max(wait, t + self.window - now)
        if lim.max_concurrent and len(self._leases) >= lim.max_concurrent:
            wait = max(wait, min(self._leases.values()) - now if self._leases else 0.0)
        return max(wait, 0.0)

    def grant(self, tokens: int, lease_s: float, now: float) -> int:
        gid = next(self._ids)
        if self.limits.requests_per_min:
            # A grant made a little late (the loop woke up late) keeps the schedule: up to
            # `slack` of lateness is not lost, so pacing does not drift below the rate. The
            # log of grants above still caps every window.
            self._tat = max(self._tat, now - self.slack) + self.interval
            self._requests.append(now)
        if self.limits.tokens_per_min:
            entry = [now, tokens, gid]
            self._tokens.append(entry)
            self._token_entry[gid] = entry
            self._token_sum += tokens
        self._leases[gid] = now + lease_s
        self.granted += 1
        return gid

    def release(self, gid: int, tokens: int | None) -> None:
        self._leases.pop(gid, None)
        entry = self._token_entry.get(gid)
        if entry is not None and tokens is not None:
            self._token_sum += tokens - entry[1]
            entry[1] = tokens

    def stats(self) -> dict:
        return {
            "granted": self.granted,
            "in_flight": len(self._leases),
            "expired_leases": self.expired,
            "requests_in_window": len(self._requests),
            "tokens_in_window": self._token_sum,
        }


class _Waiter:
    __slots__ = ("fut", "tokens", "lease_s", "ticket", "abandon_at")

    def __init__(self, fut: asyncio.Future, tokens: int, lease_s: float, ticket: str | None, abandon_at: float) -> None:
        self.fut, self.tokens, self.lease_s, self.ticket, self.abandon_at = fut, tokens, lease_s, ticket, abandon_at


class AsyncRateLimiter:
    """FIFO waiters over a `RateLimiterCore`; must be used from one event loop.

    Remote callers wait in bounded polls (`max_wait_s`) and pass the same `ticket` on
    every poll of one request, so a poll that times out keeps its place in the queue
    (re-queueing at the back would starve unlucky requests). A ticket not polled again
    within `ABANDON_S` of its last poll's end is dropped (its caller is gone).
    """

    ABANDON_S = 30.0

    def __init__(self, limits: RateLimits, clock: Callable[[], float] = time.monotonic) -> None:
        self.core = RateLimiterCore(limits)
        self.clock = clock
        self._waiters: deque[_Waiter] = deque()
        self._tickets: dict[str, _Waiter] = {}
        self._wake: asyncio.Event | None = None
        self._pump_task: asyncio.Task | None = None

    def _ensure_pump(self) -> None:
        loop = asyncio.get_running_loop()
        if self._pump_task is None or self._pump_task.done() or self._pump_task.get_loop() is not loop:
            self._waiters = deque(w for w in self._waiters if w.fut.get_loop() is loop)
            self._tickets = {t: w for t, w in self._tickets.items() if w.fut.get_loop() is loop}
            self._wake = asyncio.Event()
            self._pump_task = loop.create_task(self._pump())

    async def acquire(
        self, tokens: int, lease_s: float, max_wait_s: float | None = None, ticket: str | None = None
    ) -> int | None:
        """A grant id, or None if `max_wait_s` passed first (the caller asks again, same ticket)."""
        self._ensure_pump()
        waiter = self._tickets.get(ticket) if ticket is not None else None
        horizon = self.clock() + (max_wait_s or 0.0) + self.ABANDON_S
        if waiter is None or waiter.fut.cancelled():
            fut: asyncio.Future = asyncio.get_running_loop().create_future()
            waiter = _Waiter(fut, int(tokens), float(lease_s), ticket, horizon)
            self._waiters.append(waiter)
            if ticket is not None:
                self._tickets[ticket] = waiter
            self._wake.set()
        waiter.abandon_at = max(waiter.abandon_at, horizon)
        fut = waiter.fut
        try:
            grant = await asyncio.wait_for(asyncio.shield(fut), max_wait_s)
        except asyncio.TimeoutError:
            if not fut.done():
                if ticket is None:
                    fut.cancel()
                return None  # still queued under its ticket
            grant = fut.result()
        except asyncio.CancelledError:
            if fut.done() and not fut.cancelled():
                self.core.release(fut.result(), 0)
            else:
                fut.cancel()
            if ticket is not None:
                self._tickets.pop(ticket, None)
            raise
        if ticket is not None:
            self._tickets.pop(ticket, None)
        return grant

    async def release(self, grant: int, tokens: int | None = None) -> None:
        self.core.release(grant, tokens)
        if self._wake is not None:
            self._wake.set()

    def stats(self) -> dict:
        return {**self.core.stats(), "waiting": sum(1 for w in self._waiters if not w.fut.done())}

    async def _pump(self) -> None:
        assert self._wake is not None
        while True:
            now = self.clock()
            wait: float | None = None
            while self._waiters:
                w = self._waiters[0]
                if w.fut.done() or (w.ticket is not None and now > w.abandon_at):  # gave up / caller gone
                    self._waiters.popleft()
                    w.fut.cancel()
                    if w.ticket is not None:
                        self._tickets.pop(w.ticket, None)
                    continue
                d = self.core.delay(w.tokens, now)
                if d > 0:
                    wait = d
                    break
                self._waiters.popleft()
                w.fut.set_result(self.core.grant(w.tokens, w.lease_s, now))
            self._wake.clear()
            try:
                await asyncio.wait_for(self._wake.wait(), None if wait is None or math.isinf(wait) else wait)
            except asyncio.TimeoutError:
                pass


class LocalLimiter:
    """An in-process limiter (one process only): the `Limiter` protocol over AsyncRateLimiter."""

    def __init__(self, limits: RateLimits) -> None:
        self._lim = AsyncRateLimiter(limits)

    async def acquire(self, tokens: int, lease_s: float) -> int:
        grant = await self._lim.acquire(tokens, lease_s)
        assert grant is not None
        return grant

    async def release(self, grant: int, tokens: int) -> None:
        await self._lim.release(grant, tokens)

    def stats(self) -> dict:
        return self._lim.stats()
