"""CPU cost of an Angry Birds shot: physics alone, and a whole environment step (physics with
key-frame snapshots, the flight strip and the settled scene rendered and PNG-encoded).

    .venv/bin/python benchmarks/angrybirds_shots.py [--levels s1_l01,...] [--episodes 2]

Plays every level with the reference random baseline (angle U(0, 90), power U(0.5, 1)),
seeded, in this process, and prints CPU milliseconds (process time, so other load on the
machine does not count) per reset and per shot.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from deepphy.envs.angrybirds.env import AngryBirdsEnv
from deepphy.envs.angrybirds.levels import level_ids, load_level
from deepphy.envs.angrybirds.sim import World
from deepphy.envs.angrybirds.space import ShootSpace
from deepphy.seeding import seeded_rng


def _summary(name: str, values_ms: list[float]) -> str:
    v = np.array(values_ms)
    return (f"{name:34} n={len(v):4d}  mean {v.mean():6.1f}  median {np.median(v):6.1f}  "
            f"p90 {np.percentile(v, 90):6.1f}  max {v.max():6.1f} ms CPU")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--levels", help="comma-separated level ids (default: all 34)")
    parser.add_argument("--episodes", type=int, default=2, help="random episodes per level")
    args = parser.parse_args()
    ids = args.levels.split(",") if args.levels else level_ids()
    space = ShootSpace()
    env = AngryBirdsEnv()
    tasks = {t.id: t for t in env.tasks(env.Options())}
    resets, steps, physics, sim_seconds = [], [], [], []
    for level_id in ids:
        level = load_level(level_id)
        for episode in range(args.episodes):
            rng = seeded_rng("angrybirds-bench", level_id, episode)
            shots = [space.parse(space.reference_reply(rng)) for _ in level.birds]
            t0 = time.process_time()
            env.reset(tasks[level_id])
            resets.append(1000 * (time.process_time() - t0))
            for shot in shots:
                t0 = time.process_time()
                result = env.step(shot)
                steps.append(1000 * (time.process_time() - t0))
                sim_seconds.append(result.info["sim_time"])
                if result.done:
                    break
            # The same shots again, physics only (no snapshots, no pictures).
            world = World(level)
            for k, shot in enumerate(shots):
                t0 = time.process_time()
                world.shoot(level.birds[k], shot.angle, shot.power)
                physics.append(1000 * (time.process_time() - t0))
                if world.pigs_left == 0:
                    break
    print(f"{len(ids)} levels x {args.episodes} random episodes, {len(steps)} shots, "
          f"{statistics.mean(sim_seconds):.1f} s simulated per shot on average")
    print(_summary("reset (build + settle + render)", resets))
    print(_summary("shot, physics only", physics))
    print(_summary("shot, env.step (physics + render)", steps))


if __name__ == "__main__":
    main()
