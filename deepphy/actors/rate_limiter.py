"""One rate limiter per model endpoint, shared by every model worker of the cluster.

Design: a named async Ray actor (`num_cpus=0`, so it never waits for a CPU) per limiter
key (`ModelConfig.limiter_key`, default the model name), in the fixed namespace
`deepphy` (so concurrent runs on one cluster share an endpoint's limits), created
with `get_if_exists=True` so whichever process asks first creates it and everyone else
gets the same one. It wraps `AsyncRateLimiter`: callers queue FIFO inside the actor and
are answered when the core grants them (requests/min with pacing, tokens/min,
concurrency together; see deepphy.models.limiter).

Every Ray call is bounded: `acquire` waits inside the actor at most `POLL_S` and
returns None if not yet granted (the caller asks again with the same ticket, keeping its
place in the FIFO queue), and the caller's own await carries a timeout of
`POLL_S + CALL_TIMEOUT_S`. `release` is sent without waiting
for it; a grant that is never released (a worker killed mid-request) expires after its
lease, so concurrency slots cannot leak.

Ownership: the actor fate-shares with the process that created it. The driver should
create it before starting model workers (`ensure_limiter`), so a model worker's restart
never takes the limiter down; if a limiter does die, the handle recreates it on its
next call (its windows restart empty).
"""

from __future__ import annotations

import asyncio
import uuid
from typing import Any

import ray

from deepphy.actors.placement import beside_driver
from deepphy.models.config import ModelConfig, RateLimits
from deepphy.models.limiter import AsyncRateLimiter

POLL_S = 5.0  # longest wait inside one acquire call
CALL_TIMEOUT_S = 30.0  # slack on top of the wait for one actor call
NAME_PREFIX = "deepphy-limiter-"
NAMESPACE = "deepphy"  # cluster-wide: every run's workers find the same limiter


@ray.remote(num_cpus=0, max_concurrency=10_000)
class RateLimiterActor:
    def __init__(self, limits: dict[str, Any]) -> None:
        self.limits = RateLimits.model_validate(limits)
        self._lim = AsyncRateLimiter(self.limits)

    async def acquire(self, tokens: int, lease_s: float, max_wait_s: float = POLL_S, ticket: str | None = None) -> int | None:
        return await self._lim.acquire(tokens, lease_s, max_wait_s, ticket)

    async def release(self, grant: int, tokens: int | None = None) -> None:
        await self._lim.release(grant, tokens)

    async def stats(self) -> dict:
        return {**self._lim.stats(), "limits": self.limits.model_dump()}


def limiter_name(key: str) -> str:
    return NAME_PREFIX + key


def ensure_limiter(config: ModelConfig):
    """The endpoint's limiter actor, created if it does not exist yet (None if no limits)."""
    if not config.rate_limits.enabled:
        return None
    return RateLimiterActor.options(
        name=limiter_name(config.limiter_key), namespace=NAMESPACE, get_if_exists=True,
        scheduling_strategy=beside_driver(),
    ).remote(
        config.rate_limits.model_dump()
    )


class RayLimiter:
    """The `Limiter` protocol over the shared actor; used by clients inside Ray workers."""

    def __init__(self, config: ModelConfig) -> None:
        self.config = config
        self._actor = None

    def _handle(self):
        if self._actor is None:
            self._actor = ensure_limiter(self.config)
        return self._actor

    async def acquire(self, tokens: int, lease_s: float) -> int:
        ticket = uuid.uuid4().hex  # keeps this request's place in the queue across polls
        while True:
            try:
                grant = await asyncio.wait_for(
                    self._handle().acquire.remote(tokens, lease_s, POLL_S, ticket), POLL_S + CALL_TIMEOUT_S
                )
            except ray.exceptions.RayActorError:
                self._actor = None  # died: recreate on the next round
                await asyncio.sleep(0.5)
                continue
            except asyncio.TimeoutError:
                continue  # actor overloaded; a grant lost this way expires with its lease
            if grant is not None:
                return grant

    async def release(self, grant: int, tokens: int) -> None:
        try:
            self._handle().release.remote(grant, tokens)  # not awaited: the lease bounds a lost release
        except ray.exceptions.RayActorError:
            self._actor = None

    async def stats(self) -> dict:
        return await asyncio.wait_for(self._handle().stats.remote(), CALL_TIMEOUT_S)
