"""Kinetix decisions per second: one episode at a time versus batched stepping, in one process.

For each level size, 64 episodes (the size's levels, round-robin) each take decisions with
random actions (as MOCK does):
- one at a time: `env.step(action)` per episode, i.e. a batch of one through the compiled
  decision function, plus our rendering;
- batched: `KinetixEnv.step_many(all 64 episodes)`, one vmapped call per size.
Both include everything a worker does per decision (16 env steps, rendering the scene and
the annotated scene, PNG encoding). "physics only" times the compiled function alone.
Compilation is done first and reported separately. Episodes that end are reset.

Usage: .venv/bin/python benchmarks/kinetix_batching.py [--sizes S,M,L] [--episodes 64] [--rounds 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="S,M,L")
    ap.add_argument("--episodes", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=3, help="decisions per episode timed in each mode")
    args = ap.parse_args()

    t0 = time.perf_counter()
    from deepphy.envs.kinetix.env import KinetixEnv, KinetixOptions
    from deepphy.envs.kinetix import sim as ksim

    tasks = KinetixEnv.tasks(KinetixOptions())
    print(f"{'size':4} {'mode':28} {'decisions':>9} {'seconds':>8} {'decisions/s':>12}")
    for size in args.sizes.split(","):
        size_tasks = [t for t in tasks if t.group == size]
        envs = [KinetixEnv() for _ in range(args.episodes)]
        rng = np.random.default_rng(0)

        t = time.perf_counter()
        obs = [env.reset(size_tasks[i % len(size_tasks)]) for i, env in enumerate(envs)]
        load_s = time.perf_counter() - t

        def actions():
            return [o.action_space.sample(rng) for o in obs]

        def advance(results):
            for i, r in enumerate(results):
                obs[i] = envs[i].reset(size_tasks[i % len(size_tasks)]) if r.done else r.observation

        # Compile the two shapes used below (batch of 1, batch of `episodes`), untimed.
        s = ksim.get_sim(ksim.load_level(size_tasks[0].params["level"]))
        for n in sorted({1, args.episodes}):
            t = time.perf_counter()
            s.decide([envs[0]._state] * n, np.zeros((n, 6), np.int32))
            print(f"{size:4} {f'compile batch {n}':28} {'':>9} {time.perf_counter() - t:8.2f}")
        print(f"{size:4} {'reset 64 (levels cached)':28} {args.episodes:9d} {load_s:8.2f}")

        # One at a time.
        n = 0
        t = time.perf_counter()
        for _ in range(args.rounds):
            acts = actions()
            advance([env.step(a) for env, a in zip(envs, acts)])
            n += len(envs)
        single = n / (time.perf_counter() - t)
        print(f"{size:4} {'one at a time':28} {n:9d} {n / single:8.2f} {single:12.1f}")

        # Batched.
        n = 0
        t = time.perf_counter()
        for _ in range(args.rounds):
            advance(KinetixEnv.step_many(envs, actions()))
            n += len(envs)
        batched = n / (time.perf_counter() - t)
        print(f"{size:4} {f'batched x{args.episodes}':28} {n:9d} {n / batched:8.2f} {batched:12.1f}")

        # Physics only (the compiled decision function), same two shapes.
        states = [env._state for env in envs]
        vec = np.stack([env._vector(o.action_space.sample(rng)) for env, o in zip(envs, obs)])
        t = time.perf_counter()
        for _ in range(args.rounds):
            for i in range(len(states)):
                s.decide([states[i]], vec[i : i + 1])
        p1 = args.rounds * len(states) / (time.perf_counter() - t)
        t = time.perf_counter()
        for _ in range(args.rounds):
            s.decide(states, vec)
        pb = args.rounds * len(states) / (time.perf_counter() - t)
        print(f"{size:4} {'physics only, one at a time':28} {'':>9} {'':>8} {p1:12.1f}")
        print(f"{size:4} {f'physics only, batched x{args.episodes}':28} {'':>9} {'':>8} {pb:12.1f}")
        print(f"{size:4} ratio batched / one at a time: {batched / single:.1f}x (physics only {pb / p1:.1f}x)", flush=True)
    print(f"total {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
