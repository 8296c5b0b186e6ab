"""Fill this machine's compile caches at install time, so no user's first run waits for them.

Pooltool's kernels (numba) and Kinetix's decision functions (JAX) are compiled on first use
and kept in the per-machine cache (`deepphy.cache`): minutes of compiling, once. `make setup`
and the Docker image run this after installing, so the first `deepphy run` loads them
instead. For every environment that has a warm-up (`Environment.warm_up`), it runs that,
then plays one attempt of its first task with random valid actions, which reaches kernels
the warm-up alone does not (later shots of a Pooltool game).

    python -m deepphy.warm_up [ENV ...]    (default: every environment with a warm-up)
"""

from __future__ import annotations

import sys
import time

import numpy as np

from deepphy.envs import Environment, get_spec, specs


def compiling_envs() -> list[str]:
    """The environments whose class has its own warm-up (the others have nothing to compile)."""
    return sorted(name for name, spec in specs().items()
                  if spec.load().warm_up.__func__ is not Environment.warm_up.__func__)  # type: ignore[attr-defined]


def warm_up(name: str) -> float:
    """Warm up environment `name`'s caches; returns the seconds it took."""
    start = time.perf_counter()
    cls = get_spec(name).load()
    options = cls.Options()
    tasks = cls.tasks(options)
    cls.warm_up(options, tasks)
    env, rng = cls(options), np.random.default_rng(0)
    observation = env.reset(tasks[0])
    for _ in range(env.spec.max_steps):
        result = env.step(observation.action_space.sample(rng))
        if result.done or result.observation is None:
            break
        observation = result.observation
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    names = (sys.argv[1:] if argv is None else argv) or compiling_envs()
    for name in names:
        print(f"deepphy: warming up {name}'s compile cache ...", flush=True)
        print(f"deepphy: {name} ready in {warm_up(name):.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
