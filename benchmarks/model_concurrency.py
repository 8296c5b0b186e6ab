"""Concurrency: with 1 s server latency and no rate limit, how many requests are in flight
at once, and is throughput close to in-flight / latency?

Starts the local model server (subprocess, 127.0.0.1, --latency 1) and keeps `--in-flight`
requests going for `--duration` seconds, through one Ray model worker (the way a run
calls a model; `--direct` calls the client in this process instead; `--agent`: through
the worker hosting examples/reflection.py's agent over the endpoint, whose first attempts
pass the request on: the cost of hosting a user's agent, deepphy/agent.py). In flight is
measured by the server (the most handlers active at once); throughput counts responses
completed after a warm-up.

    .venv/bin/python benchmarks/model_concurrency.py [--in-flight 250] [--duration 30]
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(__file__))
from model_common import bench_endpoint, iphyre_requests, server_stats  # noqa: E402

from deepphy.ray_env import quiet_environment  # noqa: E402

RAY_TIMEOUT_S = 120


async def drive(call, requests, in_flight: int, duration: float, warmup: float):
    t0 = time.monotonic()
    t_end = t0 + duration
    stamps: list[float] = []

    async def lane(k: int) -> None:
        i = k
        while time.monotonic() < t_end:
            await call(requests[i % len(requests)])
            stamps.append(time.monotonic() - t0)
            i += in_flight

    await asyncio.gather(*(lane(k) for k in range(in_flight)))
    steady = [s for s in stamps if warmup <= s <= duration]
    return len(stamps), len(steady) / (duration - warmup)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--in-flight", type=int, default=250)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--warmup", type=float, default=5.0)
    ap.add_argument("--latency", type=float, default=1.0)
    ap.add_argument("--no-images", action="store_true", help="text-only prompts")
    ap.add_argument("--direct", action="store_true", help="call the client in this process, not via a Ray model worker")
    ap.add_argument("--agent", action="store_true", help="the worker hosts the reflection agent over the endpoint "
                    "(run from the repository's root)")
    a = ap.parse_args()

    quiet_environment()
    from deepphy.models import client_from_config, model_config

    # no rate_limits: nothing to enforce
    proc, url, models = bench_endpoint(a.latency, timeouts={"request_s": 60})
    requests = iphyre_requests(512, images=not a.no_images)
    ray = None
    try:
        if a.direct:
            client = client_from_config(model_config("bench", models))

            async def run():
                try:
                    return await drive(client.complete, requests, a.in_flight, a.duration, a.warmup)
                finally:
                    await client.close()
        else:
            import ray

            from deepphy.actors.model_worker import make_model_worker
            from deepphy.envs import get_spec

            from deepphy import local_ray

            local_ray.start(2, local_ray.LOOPBACK_NODE_IP, temp_dir=tempfile.mkdtemp(prefix="dpr", dir="/tmp"),
                            include_dashboard=False, object_store_memory=200 * 1024**2, logging_level=logging.WARNING)
            agent = None
            if a.agent:
                from deepphy.agent import load_agent

                agent = load_agent("examples.reflection:ReflectionAgent", {"endpoint": "bench"})
            worker = make_model_worker(agent.name if agent else "bench", get_spec("iphyre"), models_file=models,
                                       agent=agent)
            ray.get(worker.complete.remote(requests[0]), timeout=RAY_TIMEOUT_S)  # started

            async def call(req):
                return await asyncio.wait_for(worker.complete.remote(req), RAY_TIMEOUT_S)

            async def run():
                return await drive(call, requests, a.in_flight, a.duration, a.warmup)

        total, throughput = asyncio.run(run())
        st = server_stats(url, arrivals=False)
    finally:
        if ray is not None:
            ray.shutdown()
        proc.terminate()
        proc.wait(10)

    ideal = st["max_in_flight"] / a.latency
    mode = "direct" if a.direct else "Ray model worker" + (" hosting an agent" if a.agent else "")
    print(f"mode {mode}, {a.in_flight} lanes, server latency {a.latency:g} s, "
          f"images {'no' if a.no_images else 'yes (2 per request)'}, {os.cpu_count()} cores")
    print(f"server: {st['requests']} requests, most in flight at once {st['max_in_flight']}")
    print(f"throughput after {a.warmup:g} s warm-up: {throughput:.1f} req/s; in-flight/latency = {ideal:.1f} req/s; "
          f"ratio {throughput / ideal:.3f}")
    ok = st["max_in_flight"] >= 200 and throughput >= 0.8 * ideal
    print("OK" if ok else "NOT MET")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
