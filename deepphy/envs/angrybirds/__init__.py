"""Angry Birds: our own headless, physics-faithful game (pymunk), 34 levels with the bird
sequences of the reference set, scored automatically with 1-3 stars.

- `constants.py`: every number (world, materials, blocks, pigs, birds, damage, score, stars);
- `levels.py` + `levels/*.json`: the level data (pydantic), with the oracle's plans;
- `space.py`: the `shoot(angle=A, power=P)` syntax (light: no pymunk import);
- `sim.py`: the pymunk world (damage from impulses, explosions, abilities);
- `render.py`: the OpenCV side view; `env.py`: the environment; `prompt.py`: the words;
- `solve.py`: the oracle (`deepphy solve --env angrybirds ...`);
- `shortcuts.py`: the shortcut baselines (`--model shortcut-aim`, `shortcut-base`).
"""

from deepphy.envs.angrybirds.constants import MAX_BIRDS
from deepphy.envs.angrybirds.space import Shoot, ShootSpace
from deepphy.envs.base import Planning
from deepphy.envs.spec import EnvSpec, ReportSpec

SPEC = EnvSpec(
    name="angrybirds",
    title="Angry Birds",
    environment="deepphy.envs.angrybirds.env:AngryBirdsEnv",
    prompt="deepphy.envs.angrybirds.prompt:AngryBirdsPrompt",
    planning=Planning.ON_THE_FLY,
    max_attempts=1,  # one attempt per level; its decisions are the level's birds
    max_steps=MAX_BIRDS,
    report=ReportSpec(stars=True, step_checkpoints=(1, 2, 3, 4, 5, MAX_BIRDS), step_noun="shot"),
    solver="deepphy.envs.angrybirds.solve:main",
    shortcuts="deepphy.envs.angrybirds.shortcuts:SHORTCUTS",
    description="34 levels (scene 1: 21, scene 2: 13): launch the birds in order, kill every pig; 1-3 stars",
)

__all__ = ["SPEC", "Shoot", "ShootSpace"]
