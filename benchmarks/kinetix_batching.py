"""Kinetix decisions per second: one episode at a time versus batched stepping, in one process.

Every decision runs through one compiled program per size, the decision function vmapped
over `sim.BATCH` lanes (see deepphy/envs/kinetix/sim.py: batching must not change a
result). For each level size, 64 episodes (the size's levels, round-robin) take decisions
with random actions (as MOCK does):
- full step: `env.step(action)` per episode (a padded batch) versus
  `KinetixEnv.step_many(all 64)` (64 / BATCH calls), both including everything a worker
  does per decision (16 env steps, rendering the scene and the annotated scene, PNG).
- physics only: the compiled function alone, same states, one at a time and 64 at once;
  with `--old` also the earlier scheme (vmap compiled for 1 and for 64 lanes, which
  round differently from each other) and the unbatched jitted function, for reference.
Compilation is done first and reported separately. Episodes that end are reset. The
machine may be shared: "dec/CPU-s" (decisions per second of this process's CPU time) is
less sensitive to other jobs than "dec/s" (wall).

Usage: .venv/bin/python benchmarks/kinetix_batching.py [--sizes S,M,L] [--episodes 64] [--rounds 3] [--old]
"""

from __future__ import annotations

import argparse
import time
from typing import Callable

import numpy as np


def timed(fn: Callable[[], object]) -> tuple[float, float]:
    """(wall, CPU) seconds of one call."""
    w, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w, time.process_time() - c


def row(size: str, mode: str, decisions: int, wall: float, cpu: float) -> None:
    print(f"{size:4} {mode:34} {decisions:9d} {wall:8.2f} {decisions / wall:8.1f} {decisions / cpu:10.1f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="S,M,L")
    ap.add_argument("--episodes", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=3, help="decisions per episode timed in each mode")
    ap.add_argument("--old", action="store_true", help="also time the old vmap shapes (1 and 64) and the unbatched jit")
    args = ap.parse_args()

    t0 = time.perf_counter()
    import jax

    from deepphy.envs.kinetix.env import KinetixEnv, KinetixOptions
    from deepphy.envs.kinetix import sim as ksim

    tasks = KinetixEnv.tasks(KinetixOptions())
    print(f"one compiled batch shape: {ksim.BATCH} lanes")
    print(f"{'size':4} {'mode':34} {'decisions':>9} {'seconds':>8} {'dec/s':>8} {'dec/CPU-s':>10}")
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

        s = ksim.get_sim(ksim.load_level(size_tasks[0].params["level"]))
        wall, _ = timed(lambda: s.decide([envs[0]._state], np.zeros((1, 6), np.int32)))
        print(f"{size:4} {f'compile (batch {ksim.BATCH})':34} {'':>9} {wall:8.2f}")
        print(f"{size:4} {f'reset {args.episodes} (levels cached)':34} {args.episodes:9d} {load_s:8.2f}")

        n = args.rounds * len(envs)
        row(size, "full step, one at a time", n, *timed(
            lambda: [advance([env.step(a) for env, a in zip(envs, actions())]) for _ in range(args.rounds)]))
        row(size, f"full step, step_many x{args.episodes}", n, *timed(
            lambda: [advance(KinetixEnv.step_many(envs, actions())) for _ in range(args.rounds)]))

        # Physics only: the same states and actions for every variant.
        states = [env._state for env in envs]
        vec = np.stack([env._vector(o.action_space.sample(rng)) for env, o in zip(envs, obs)])
        row(size, "physics, one at a time", n, *timed(
            lambda: [s.decide([x], v[None]) for _ in range(args.rounds) for x, v in zip(states, vec)]))
        row(size, f"physics, x{args.episodes} at once", n, *timed(
            lambda: [s.decide(states, vec) for _ in range(args.rounds)]))
        if args.old:
            # Timed like `Sim.decide`: stack the inputs, fetch the outputs.
            vmapped = jax.jit(jax.vmap(s.decision, in_axes=(0, 0, None)))
            unbatched = jax.jit(s.decision)

            def stack(xs):
                return jax.tree.map(lambda *x: np.stack(x), *xs)

            def old_one():
                return [jax.device_get(vmapped(stack([x]), v[None], s.env_params)) for x, v in zip(states, vec)]

            def old_all():
                return jax.device_get(vmapped(stack(states), vec, s.env_params))

            def plain():
                return [jax.device_get(unbatched(x, v, s.env_params)) for x, v in zip(states, vec)]

            variants = [
                ("old vmap 1, one at a time", old_one, lambda: vmapped(stack(states[:1]), vec[:1], s.env_params)),
                (f"old vmap {args.episodes}, at once", old_all, old_all),
                ("unbatched jit, one at a time", plain, lambda: unbatched(states[0], vec[0], s.env_params)),
            ]
            for label, fn, compile_it in variants:
                wall, _ = timed(lambda: jax.block_until_ready(compile_it()))
                print(f"{size:4} {'compile ' + label.split(',')[0]:34} {'':>9} {wall:8.2f}")
                row(size, f"physics, {label}", n, *timed(lambda: [fn() for _ in range(args.rounds)]))
    print(f"total {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
