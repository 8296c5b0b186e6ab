"""Pooltool: single-player nine-ball on the real `pooltool-billiards` package.

- `space.py`: the shot syntax and the game's constants (light: no pooltool import);
- `sim.py`: pooltool itself (numba cache, physics engine, warm-up, racks, placement);
- `render.py`: the top-down OpenCV render;
- `env.py`: the environment (rules, ball in hand, observations); `prompt.py`: the words.
"""

from deepphy.envs.base import Planning
from deepphy.envs.pooltool.space import MAX_SHOTS, PoolShot, PoolSpace
from deepphy.envs.spec import EnvSpec, ReportSpec

SPEC = EnvSpec(
    name="pooltool",
    title="Pooltool",
    environment="deepphy.envs.pooltool.env:PooltoolEnv",
    prompt="deepphy.envs.pooltool.prompt:PooltoolPrompt",
    planning=Planning.ON_THE_FLY,
    max_attempts=1,  # one game per task
    max_steps=MAX_SHOTS,
    report=ReportSpec(step_checkpoints=(1, 3, 6, 9, 12, 15), step_noun="shot"),
    shortcuts="deepphy.envs.pooltool.shortcuts:SHORTCUTS",
    description="100 seeded nine-ball racks: choose cue speed and strike spot, pot the 9-ball legally",
)

__all__ = ["SPEC", "PoolShot", "PoolSpace"]
