"""Rate limit from the provider's side: R requests/min through the shared Ray limiter.

Starts the local model server (subprocess, 127.0.0.1), a local Ray cluster, the endpoint's
limiter actor and several model workers that all consult it, then keeps `--outstanding`
requests queued for `--duration` seconds. The server's arrival log is the judge: the most
arrivals in any 60 s window must not exceed R, and the achieved rate must be >= 95% of R.

    .venv/bin/python benchmarks/model_rate_limit.py [--rpm 600] [--duration 150] [--workers 4]
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys
import tempfile
import time
import urllib.request

sys.path.insert(0, os.path.dirname(__file__))
from model_common import bench_endpoint, iphyre_requests, max_in_window, server_stats  # noqa: E402

from deepphy import local_ray  # noqa: E402
from deepphy.ray_env import quiet_environment  # noqa: E402

RAY_TIMEOUT_S = 120


async def drive(workers, requests, duration: float, outstanding: int) -> int:
    sem = asyncio.Semaphore(outstanding)
    done = 0
    errors: list[str] = []
    t_end = time.monotonic() + duration

    async def one(i: int) -> None:
        nonlocal done
        t = time.monotonic()
        try:
            await asyncio.wait_for(workers[i % len(workers)].complete.remote(requests[i % len(requests)]), RAY_TIMEOUT_S)
            done += 1
        except Exception as e:  # noqa: BLE001 - counted and shown
            errors.append(f"request {i} after {time.monotonic() - t:.1f} s: {type(e).__name__}: {str(e)[:200]}")
        finally:
            sem.release()

    tasks, i = [], 0
    while time.monotonic() < t_end:
        await sem.acquire()
        tasks.append(asyncio.ensure_future(one(i)))
        i += 1
    await asyncio.gather(*tasks)
    for line in errors[:5]:
        print("error:", line)
    return done


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rpm", type=float, default=600)
    ap.add_argument("--duration", type=float, default=150.0, help="seconds of submitting")
    ap.add_argument("--workers", type=int, default=4, help="model worker actors sharing the limiter")
    ap.add_argument("--outstanding", type=int, default=64, help="requests queued at once")
    ap.add_argument("--latency", type=float, default=0.2, help="server latency per request (s)")
    ap.add_argument("--margin", type=float, default=1.0, help="limiter window margin (s)")
    a = ap.parse_args()

    quiet_environment()
    import ray

    from deepphy.actors.model_worker import make_model_worker
    from deepphy.envs import get_spec
    from deepphy.actors.rate_limiter import ensure_limiter
    from deepphy.models import model_config

    proc, url, models = bench_endpoint(
        a.latency, timeouts={"request_s": 30},
        rate_limits={"requests_per_min": a.rpm, "window_margin_s": a.margin},
    )
    try:  # from here on, the server is stopped however this ends (Ray's start failing included)
        local_ray.start(2, local_ray.LOOPBACK_NODE_IP, temp_dir=tempfile.mkdtemp(prefix="dpr", dir="/tmp"),
                        include_dashboard=False, object_store_memory=200 * 1024**2, logging_level=logging.WARNING)
        limiter = ensure_limiter(model_config("bench", models))
        workers = [make_model_worker("bench", get_spec("iphyre"), models_file=models) for _ in range(a.workers)]
        requests = iphyre_requests(64)
        # warm up: every worker started and connected, then the server's log starts empty
        ray.get([w.complete.remote(requests[i]) for i, w in enumerate(workers)], timeout=RAY_TIMEOUT_S)
        urllib.request.urlopen(urllib.request.Request(url + "/admin/reset", method="POST"), timeout=60).read()
        t0 = time.time()
        done = asyncio.run(drive(workers, requests, a.duration, a.outstanding))
        wall = time.time() - t0
        st = server_stats(url)
        lim = ray.get(limiter.stats.remote(), timeout=RAY_TIMEOUT_S)
    finally:
        ray.shutdown()
        proc.terminate()
        proc.wait(10)

    t = sorted(st["arrivals"])
    n = len(t)
    span = t[-1] - t[0]
    achieved = (n - 1) / span * 60 if span > 0 else 0.0
    worst = max_in_window(t, 60.0)
    full = [sum(1 for x in t if t[0] + 60 * k <= x < t[0] + 60 * (k + 1)) for k in range(int(span // 60))]
    print(f"workers {a.workers}, limit R = {a.rpm:g} requests/min, window margin {a.margin:g} s, server latency {a.latency:g} s")
    print(f"completed {done} requests in {wall:.1f} s; server saw {n} arrivals over {span:.1f} s "
          f"(statuses {st['status']}); limiter {lim}")
    print(f"most arrivals in any 60 s window: {worst} (allowed {a.rpm:g}) -> {'OK' if worst <= a.rpm else 'EXCEEDED'}")
    print(f"arrivals per consecutive full minute: {full}")
    gaps = sorted(b - x for x, b in zip(t, t[1:]))
    print(f"gaps between arrivals: median {gaps[len(gaps) // 2]:.4f} s, p1 {gaps[len(gaps) // 100]:.4f} s, "
          f"p99 {gaps[len(gaps) * 99 // 100]:.4f} s (pacing interval {(60 + a.margin) / a.rpm:.4f} s)")
    print(f"achieved/allowed = {achieved:.1f}/{a.rpm:g} per min = {achieved / a.rpm:.3f} "
          f"({'OK' if achieved >= 0.95 * a.rpm else 'BELOW 95%'})")
    sys.exit(0 if worst <= a.rpm and achieved >= 0.95 * a.rpm else 1)


if __name__ == "__main__":
    try:
        main()
    except local_ray.RayStartFailed as e:
        sys.exit(f"model_rate_limit: error: {e}")
