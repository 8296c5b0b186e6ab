"""Cut the Rope cost: CPU time per simulated second (physics and element rules only) and
per action (the environment's step: physics, the key frame and the next observation,
both rendered and PNG-encoded), over every level's stored plan.

    uv run python benchmarks/cuttherope_speed.py [--repeat 3] [--levels b1_l01,...]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

from deepphy.envs.cuttherope.env import CutTheRopeEnv
from deepphy.envs.cuttherope.level import level_ids, load_level
from deepphy.envs.cuttherope.oracle import act
from deepphy.envs.cuttherope.sim import World
from deepphy.envs.cuttherope.space import CutSpace


def physics(ids: list[str]) -> tuple[float, float]:
    """(CPU seconds, simulated seconds) playing every stored plan on the bare world."""
    space = CutSpace(num_pins=9, num_active_pins=9, num_bubbles=9, num_cushions=9, pins=list(range(1, 10)),
                     active_pins=list(range(1, 10)), bubbles=list(range(1, 10)))
    cpu = simulated = 0.0
    for level_id in ids:
        level = load_level(level_id)
        actions = [space.parse(t) for t in level.solution.actions]
        world = World.from_level(level)
        start = time.process_time()
        for a in actions:
            act(world, a)
            if world.decided:
                break
        cpu += time.process_time() - start
        simulated += world.time
    return cpu, simulated


def env_steps(ids: list[str]) -> tuple[float, int, float, int]:
    """(CPU seconds in step, actions, CPU seconds in reset, resets) through the environment."""
    env = CutTheRopeEnv()
    step_cpu = reset_cpu = 0.0
    steps = resets = 0
    for level_id in ids:
        level = load_level(level_id)
        start = time.process_time()
        obs = env.start(level)
        reset_cpu += time.process_time() - start
        resets += 1
        for text in level.solution.actions:
            action = obs.action_space.parse(text)
            start = time.process_time()
            result = env.step(action)
            step_cpu += time.process_time() - start
            steps += 1
            if result.done:
                break
            obs = result.observation
    return step_cpu, steps, reset_cpu, resets


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--levels", help="comma-separated ids (default: all 88)")
    args = p.parse_args()
    ids = args.levels.split(",") if args.levels else level_ids()

    per_sim_s, per_action, per_reset = [], [], []
    for _ in range(args.repeat):
        cpu, simulated = physics(ids)
        per_sim_s.append(1000 * cpu / simulated)
        step_cpu, steps, reset_cpu, resets = env_steps(ids)
        per_action.append(1000 * step_cpu / steps)
        per_reset.append(1000 * reset_cpu / resets)
    print(f"{len(ids)} levels, stored plans, best of {args.repeat} (CPU time, one process):")
    print(f"  physics + element rules: {min(per_sim_s):6.2f} ms CPU per simulated second "
          f"(median {statistics.median(per_sim_s):.2f}; {simulated:.0f} s simulated per pass)")
    print(f"  env.step (physics, key frame, next observation, PNGs): {min(per_action):6.2f} ms CPU per action "
          f"(median {statistics.median(per_action):.2f}; {steps} actions per pass)")
    print(f"  reset (build, first render, PNG): {min(per_reset):6.2f} ms CPU per attempt")
    return 0


if __name__ == "__main__":
    sys.exit(main())
