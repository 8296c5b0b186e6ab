"""Thousands of episodes in flight: the real pipeline (I-PHYRE, the Ray actors, the run
store) against the local model server over HTTP with a fixed latency per request.

Two parts, printed side by side with their ideal:
1. a sweep of episodes in flight N: attempts/s measured against the ideal N / latency
   (each episode has one request outstanding), until the machine is CPU-bound;
2. long runs keeping `--episodes` in flight: a timeline of episodes in flight, attempts
   done and per second, and the driver's CPU and resident memory (anonymous and shared).
   The same size of run is done `--repeats` times in one driver. The first run grows the
   heap to the working set of that many episodes in flight (their requests, Ray's copies,
   their records so far); later runs reuse it. What must not happen is memory that stays
   per attempt: so each run prints its growth from its second sample to its end, and after
   each run the driver's memory is printed before and after malloc_trim (free heap the C
   allocator keeps is not memory in use) with the count of live Python objects (gc).

    uv run python benchmarks/in_flight.py [--latency 1.0] [--sweep 25,50,100] [--episodes 2400]
                                          [--attempts 20000] [--repeats 2] [--num-cpus 2]
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import os
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(__file__))

from model_common import bench_endpoint  # noqa: E402

from deepphy.ray_env import quiet_environment  # noqa: E402

quiet_environment()

import psutil  # noqa: E402
import ray  # noqa: E402

from deepphy.config import RunConfig, RuntimeOptions  # noqa: E402
from deepphy.ray_connect import ensure_ray  # noqa: E402
from deepphy.runner import evaluate  # noqa: E402
from deepphy.runs.store import read_records  # noqa: E402

GAMES = 40  # I-PHYRE's tasks; episodes = GAMES x runs


def steady_rate(out: str) -> float:
    """Attempts finished per second between the 20th and 80th percentile of finish times."""
    ends = sorted(r.timing.finished for r in read_records(out))
    lo, hi = ends[len(ends) // 5], ends[4 * len(ends) // 5]
    return (4 * len(ends) // 5 - len(ends) // 5) / (hi - lo) if hi > lo else 0.0


def run(config: RunConfig, runtime: RuntimeOptions, out: str, sample_s: float | None = None):
    """evaluate() in a thread; with `sample_s`, a timeline of the driver and the run."""
    done: dict = {}
    thread = threading.Thread(target=lambda: done.update(outcome=evaluate(config, out, runtime)))
    me = psutil.Process()
    me.cpu_percent()
    t0 = time.perf_counter()
    thread.start()
    timeline = []
    while thread.is_alive():
        thread.join(sample_s or 1.0)
        if sample_s and thread.is_alive():
            snap = _snapshot()
            timeline.append((time.perf_counter() - t0, snap.get("in_flight", 0), snap.get("attempts", 0),
                             me.cpu_percent(), *driver_memory_mb()))
    return done.get("outcome"), time.perf_counter() - t0, timeline


def driver_memory_mb() -> tuple[float, float, float]:
    """The driver's resident memory in MB: total, anonymous (its heaps) and shared (pages of
    Ray's object store it has mapped and touched; they stay counted after objects are freed)."""
    fields = {}
    with open("/proc/self/status") as f:
        for line in f:
            key, _, value = line.partition(":")
            if key in ("VmRSS", "RssAnon", "RssShmem"):
                fields[key] = int(value.split()[0]) / 1024
    return fields.get("VmRSS", 0.0), fields.get("RssAnon", 0.0), fields.get("RssShmem", 0.0)


def trim() -> None:
    """Hand the C heap's free pages back to the OS (glibc): what RSS keeps after this is
    memory in use, not free memory the allocator holds on to."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass


def _snapshot() -> dict:
    for actor in ray.util.list_named_actors(all_namespaces=True):
        if actor["name"].startswith("deepphy/") and actor["name"].endswith("/metrics"):
            try:
                handle = ray.get_actor(actor["name"], namespace=actor["namespace"])
                return ray.get(handle.snapshot.remote(), timeout=10)
            except Exception:  # noqa: BLE001 - between runs
                return {}
    return {}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--latency", type=float, default=1.0, help="seconds the server takes per request")
    ap.add_argument("--sweep", default="25,50,100", help="episodes in flight for part 1 ('' to skip)")
    ap.add_argument("--episodes", type=int, default=2400, help="episodes in flight for part 2 (0 to skip)")
    ap.add_argument("--attempts", type=int, default=20_000, help="about this many attempts in part 2")
    ap.add_argument("--repeats", type=int, default=2, help="long runs, one after another in this driver")
    ap.add_argument("--num-cpus", type=int, default=2)
    args = ap.parse_args()

    server, url, models = bench_endpoint(args.latency, timeouts={"request_s": 600.0}, max_images=3000)
    runtime = RuntimeOptions(num_cpus=args.num_cpus, progress=False, models_file=models, model_timeout_s=3600)
    try:  # the server is stopped however this ends (Ray's start failing included)
        ensure_ray(runtime)
        for n in [int(x) for x in args.sweep.split(",") if x]:
            runs = max(3, 3 * n // GAMES)  # three waves of N episodes
            config = RunConfig(env="iphyre", model="bench", runs=runs, seed=1)
            with tempfile.TemporaryDirectory() as out:
                outcome, wall, _ = run(config, runtime.model_copy(update={"max_in_flight": n}), out)
                rate = steady_rate(out)
            ideal = n / args.latency
            print(f"in flight {n:5d}: {outcome.new_records:6d} attempts, steady {rate:7.1f} attempts/s, "
                  f"ideal {ideal:7.1f}/s, ratio {rate / ideal:.2f} ({wall:.0f} s wall)", flush=True)
        if args.episodes:
            # I-PHYRE episodes take ~7.5 MOCK attempts on average (reference baseline: ~6).
            runs = max(args.episodes // GAMES, round(args.attempts / 6.0 / GAMES))
            before = driver_memory_mb()
            print(f"\nbefore the runs: driver RSS {before[0]:.0f} MB (anonymous {before[1]:.0f})", flush=True)
            ends = []
            for repeat in range(1, args.repeats + 1):
                config = RunConfig(env="iphyre", model="bench", runs=runs, seed=1 + repeat)
                with tempfile.TemporaryDirectory() as out:
                    outcome, wall, timeline = run(config, runtime.model_copy(update={"max_in_flight": args.episodes}),
                                                  out, sample_s=10.0)
                    rate = steady_rate(out)
                del outcome
                gc.collect()
                end = driver_memory_mb()
                trim()
                ends.append((end, driver_memory_mb(), len(gc.get_objects())))
                print(f"\nrun {repeat}: {GAMES * runs} episodes, up to {args.episodes} in flight: "
                      f"{timeline[-1][2] if timeline else 0} attempts in {wall:.0f} s; steady {rate:.1f} attempts/s "
                      f"(ideal at this latency {args.episodes / args.latency:.0f}/s until CPU-bound); "
                      f"peak in flight {max((x[1] for x in timeline), default=0)}")
                print(f"{'t (s)':>7} {'in flight':>9} {'attempts':>9} {'per s':>7} {'driver CPU %':>12} "
                      f"{'driver RSS MB':>13} {'anon':>6} {'shmem':>6}")
                last_t, last_n = 0.0, 0
                for t, inflight, n, cpu, rss, anon, shmem in timeline:
                    print(f"{t:7.0f} {inflight:9d} {n:9d} {(n - last_n) / (t - last_t):7.1f} {cpu:12.0f} {rss:13.0f} "
                          f"{anon:6.0f} {shmem:6.0f}")
                    last_t, last_n = t, n
                if len(timeline) >= 2:
                    (_, _, n0, _, rss0, *_), (_, _, n1, _, rss1, *_) = timeline[1], timeline[-1]
                    print(f"within run {repeat}: RSS {rss1 - rss0:+.0f} MB from attempt {n0} to {n1} "
                          f"({n1 - n0} attempts)")
                (rss, anon, _), (rss_t, anon_t, _), objects = ends[-1]
                print(f"after run {repeat}: driver RSS {rss:.0f} MB (anonymous {anon:.0f}); after malloc_trim "
                      f"{rss_t:.0f} MB (anonymous {anon_t:.0f}); {objects} live Python objects", flush=True)
            first, last = ends[0], ends[-1]
            print(f"\ndriver memory after run {len(ends)} against after run 1 ({len(ends) - 1} x ~{timeline[-1][2] if timeline else 0} "
                  f"more attempts, the same in-flight working set): RSS {last[0][0] - first[0][0]:+.0f} MB, after malloc_trim "
                  f"{last[1][0] - first[1][0]:+.0f} MB, live Python objects {last[2] - first[2]:+d}")
    finally:
        server.terminate()
        ray.shutdown()


if __name__ == "__main__":
    main()
