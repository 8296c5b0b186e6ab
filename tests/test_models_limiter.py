"""The rate limiter: the core's windows on a simulated clock, then for real over HTTP, in
one process and shared by several Ray model workers (checked from the server's side)."""

from __future__ import annotations

import asyncio
import bisect
import time

import pytest
import yaml

from deepphy.models import ModelError, client_from_config
from deepphy.models.config import RateLimits
from deepphy.models.limiter import LocalLimiter, RateLimiterCore
from deepphy.testing.model_server import ServerConfig, ServerThread
from models_support import iphyre_request, local_config

RAY_TIMEOUT_S = 120


def max_in_window(times: list[float], window: float) -> int:
    times = sorted(times)
    return max((bisect.bisect_right(times, t + window) - i for i, t in enumerate(times)), default=0)


def simulate(core: RateLimiterCore, n: int, tokens=lambda i: 1, actual=lambda i: None, hold: float = 0.0):
    """Grant `n` requests as early as the core allows; returns grant times."""
    now, out, held = 0.0, [], []
    while len(out) < n:
        while held and held[0][0] <= now:
            core.release(held.pop(0)[1], actual(len(out)))
        d = core.delay(tokens(len(out)), now)
        if d > 0:
            nxt = min([now + d] + [h[0] for h in held])
            now = max(nxt, now + 1e-9)
            continue
        gid = core.grant(tokens(len(out)), 1000.0, now)
        if hold:
            held.append((now + hold, gid))
            held.sort()
        else:
            core.release(gid, actual(len(out)))
        out.append(now)
    return out


def test_requests_per_minute_window_and_pacing():
    core = RateLimiterCore(RateLimits(requests_per_min=100, window_margin_s=1.0))
    t = simulate(core, 500)
    assert max_in_window(t, 60.0) <= 100 and max_in_window(t, 61.0 - 1e-6) <= 100  # the core's window is (now - 61, now]
    achieved = (len(t) - 1) / (t[-1] - t[0]) * 60
    assert 0.95 * 100 <= achieved <= 100
    gaps = [b - a for a, b in zip(t, t[1:])]
    assert min(gaps) >= 0.0 and sorted(gaps)[len(gaps) // 10] == pytest.approx(0.61)  # paced, not bursty
    assert sorted(gaps)[len(gaps) // 2] == pytest.approx(0.61)


def test_burst_then_pace():
    core = RateLimiterCore(RateLimits(requests_per_min=60, burst=5, window_margin_s=0.0))
    t = simulate(core, 200)
    assert t[:5] == [0.0] * 5 and max_in_window(t, 60.0 - 1e-6) <= 60  # no margin: half-open window


def test_tokens_per_minute_uses_actual_usage():
    core = RateLimiterCore(RateLimits(tokens_per_min=1000, window_margin_s=0.0))
    t = simulate(core, 10, tokens=lambda i: 300)
    assert max_in_window(t, 59.999) == 3  # 3 x 300 estimated tokens fit, a 4th does not
    core = RateLimiterCore(RateLimits(tokens_per_min=1000, window_margin_s=0.0))
    t = simulate(core, 10, tokens=lambda i: 300, actual=lambda i: 100)
    assert max_in_window(t, 59.999) == 8  # estimates corrected down to what was used
    core = RateLimiterCore(RateLimits(tokens_per_min=1000))
    assert simulate(core, 2, tokens=lambda i: 5000)[0] == 0.0  # one oversized request still goes


def test_concurrency_and_lease_expiry():
    core = RateLimiterCore(RateLimits(max_concurrent=2))
    t = simulate(core, 6, hold=10.0)
    assert t == [0.0, 0.0, 10.0, 10.0, 20.0, 20.0]
    core = RateLimiterCore(RateLimits(max_concurrent=1))
    core.grant(1, 5.0, 0.0)  # never released: its worker died
    assert core.delay(1, 0.0) == pytest.approx(5.0)
    assert core.delay(1, 5.0) == 0.0 and core.stats()["expired_leases"] == 1


def test_all_limits_together():
    core = RateLimiterCore(RateLimits(requests_per_min=30, tokens_per_min=2000, max_concurrent=1, window_margin_s=0))
    t = simulate(core, 60, tokens=lambda i: 100, hold=1.0)
    assert max_in_window(t, 59.999) <= 20  # tokens bind: 2000 / 100
    assert min(b - a for a, b in zip(t, t[1:])) >= 1.0 - 1e-9  # one at a time, each held 1 s


# --- over HTTP -----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def server():
    with ServerThread(ServerConfig()) as s:
        yield s


def test_local_limiter_concurrency_seen_by_server(server):
    server.reset()
    server.configure(latency_s=0.3)
    cfg = local_config(server.url, "openai", rate_limits={"max_concurrent": 3})

    async def go():
        # Explicitly local: whether a Ray session exists depends on which tests ran before.
        client = client_from_config(cfg, limiter=LocalLimiter(cfg.rate_limits))
        try:
            return await asyncio.gather(*(client.complete(iphyre_request(i % 6, run=i)) for i in range(12)))
        finally:
            await client.close()

    asyncio.run(go())
    st = server.stats()
    assert st["requests"] == 12 and st["max_in_flight"] == 3


def test_local_limiter_paces_requests(server):
    server.reset()
    server.configure(latency_s=0.0)
    cfg = local_config(server.url, "gemini", rate_limits={"requests_per_min": 600})

    async def go():
        client = client_from_config(cfg, limiter=LocalLimiter(cfg.rate_limits))
        try:
            await asyncio.gather(*(client.complete(iphyre_request(i % 6, run=i)) for i in range(11)))
        finally:
            await client.close()

    asyncio.run(go())
    t = sorted(server.stats()["arrivals"])
    assert t[-1] - t[0] >= 9 * 61 / 600 - 0.05  # paced (one interval of slack after idle)


def test_ray_limiter_is_shared_by_model_workers(ray_cluster, server, tmp_path):
    import ray

    from deepphy.actors.model_worker import make_model_worker
    from deepphy.envs import get_spec
    from deepphy.actors.rate_limiter import ensure_limiter

    server.reset()
    server.configure(latency_s=0.2)
    cfg = local_config(server.url, "openai", name="shared-local", rate_limits={"requests_per_min": 1200, "max_concurrent": 4})
    models = tmp_path / "models.yaml"
    models.write_text(yaml.safe_dump({"models": [cfg.model_dump(mode="json", exclude_defaults=True)]}))
    limiter = ensure_limiter(cfg)  # the driver owns the limiter
    workers = [make_model_worker("shared-local", get_spec("iphyre"), models_file=str(models)) for _ in range(3)]
    try:
        refs = [workers[i % 3].complete.remote(iphyre_request(i % 6, run=i)) for i in range(24)]
        out = ray.get(refs, timeout=RAY_TIMEOUT_S)
        assert all(r.text for r in out)
        st = server.stats()
        assert st["requests"] == 24 and st["max_in_flight"] <= 4
        t = sorted(st["arrivals"])
        assert t[-1] - t[0] >= 23 * 61 / 1200 * 0.9  # paced across workers, not per worker
        deadline = time.monotonic() + 30  # releases are sent without waiting: the last may still be on its way
        while (lstats := ray.get(limiter.stats.remote(), timeout=RAY_TIMEOUT_S))["in_flight"] and time.monotonic() < deadline:
            time.sleep(0.1)
        assert lstats["granted"] == 24 and lstats["in_flight"] == 0

        # a ModelError crosses Ray with its retry count and kind
        server.configure(faults={"rate": 1.0, "kinds": ["500"]})
        with pytest.raises(ModelError) as e:
            ray.get(workers[0].complete.remote(iphyre_request(0, run=99)), timeout=RAY_TIMEOUT_S)
        assert e.value.retries == 3 and e.value.kind == "http_500"
        server.configure(faults={"rate": 0.0})

        # what the driver's progress line reads: requests of a worker waiting for the shared limit
        from deepphy.scheduler import WorkerModel

        async def watch():
            model = WorkerModel(workers[0])
            calls = [asyncio.ensure_future(model.complete(iphyre_request(i % 6, run=200 + i))) for i in range(12)]
            seen = []
            while not all(c.done() for c in calls):
                seen.append(await model.activity())
                await asyncio.sleep(0.02)
            await asyncio.gather(*calls)
            return seen, await model.activity()

        seen, after = asyncio.run(watch())
        assert max(a["rate_limited"] for a in seen) >= 4 and after["rate_limited"] == after["retrying"] == 0
    finally:
        server.configure(faults={"rate": 0.0})
        for w in workers:
            ray.kill(w)
        ray.kill(limiter)


def test_polling_callers_keep_their_place_in_the_queue():
    """Remote callers poll in short waits; with a ticket a timed-out poll keeps its place,
    so grants follow arrival order (no starvation), and a caller that never comes back is
    dropped instead of holding the queue."""
    from deepphy.models.limiter import AsyncRateLimiter

    async def go():
        lim = AsyncRateLimiter(RateLimits(requests_per_min=1200, window_margin_s=0.0))  # one per 50 ms
        lim.ABANDON_S = 0.2
        order: list[int] = []

        async def caller(i: int) -> None:
            await asyncio.sleep(i * 0.001)  # arrive in order
            while (g := await lim.acquire(1, 10.0, max_wait_s=0.07, ticket=f"t{i}")) is None:
                pass
            order.append(i)
            await lim.release(g, 1)

        await asyncio.gather(*(caller(i) for i in range(15)))
        return order, lim.stats()

    order, stats = asyncio.run(go())
    assert order == list(range(15)) and stats["waiting"] == 0


def test_abandoned_ticket_gets_no_grant():
    from deepphy.models.limiter import AsyncRateLimiter

    async def go():
        lim = AsyncRateLimiter(RateLimits(max_concurrent=1))
        lim.ABANDON_S = 0.1
        held = await lim.acquire(1, 10.0)
        assert await lim.acquire(1, 10.0, max_wait_s=0.05, ticket="gone") is None  # polls once, never again
        await asyncio.sleep(0.3)
        await lim.release(held, 1)
        assert await lim.acquire(1, 10.0, max_wait_s=1.0, ticket="next") is not None
        return lim.stats()

    stats = asyncio.run(go())
    assert stats["in_flight"] == 1 and stats["waiting"] == 0  # only "next" holds a slot
